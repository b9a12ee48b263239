"""What a rendered PSF is (:class:`PSFSpec`), checked and planned before any rendering
(:func:`plan_render`, :func:`check_render_budget`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..limits import DEFAULT_MAX_SAMPLES, check_count
from ..model.camera import MIN_FOCUS_MM, CameraDesign
from ..psf.analytic import design_psf
from .diffraction import channels, diffracted_model, sensor_params
from .film import FILM_MODES, Film, film_for
from .mode_setup import ModeSetup, mode_setup

AUTO_PARTICLES = 1 << 18
"""``spp=None``: enough samples per pixel for about this many particles per window."""
MAX_SPP = 1 << 20
INTEGRATORS = ("ptracer", "path")
MIN_DEPTH_MM, MAX_DEPTH_MM = MIN_FOCUS_MM, 1.0e6


@dataclass(frozen=True)
class PSFSpec:
    """What to render: a PSF of ``mode`` at image speed ``velocity`` (px/ms).

    ``size``: odd int or (h, w), default the analytic kernel's automatic size. ``spp``:
    Mitsuba's samples per film pixel for each window (None: :func:`auto_spp`, about 2^18
    particles per window on the kernel-sized film). ``film``: ``window`` (a kernel-sized
    film) or ``crop`` (of the whole film). ``integrator``: ``ptracer`` or ``path``.
    ``per_window=False`` renders the whole exposure at once (no trajectory);
    ``keep_windows`` keeps each window's image. ``threads``: Dr.Jit worker threads while
    rendering; 1 (default) makes the same seed give bit-identical kernels (ptracer's float32
    atomic adds otherwise run in a thread-dependent order), None keeps the current count.
    ``origin``: what the kernel's centre pixel stands for, as in
    :func:`~pacam_render.psf.design_psf` (``t0`` or ``pinhole``). ``max_samples``: refuse a
    render of more particles (:func:`check_render_budget`). Checked by :func:`plan_render`,
    whose errors name these fields. ``diffraction``: the opening's diffraction in the rays,
    and the model convolved alike (:mod:`.diffraction`), on pixels of ``pixel_pitch_mm``
    (default the design's own; a binned sensor's are larger).
    """

    mode: str = "coded"
    velocity: float = 0.0
    size: int | tuple[int, int] | None = None
    spp: int | None = None
    seed: int = 0
    film: str = "window"
    integrator: str = "ptracer"
    per_window: bool = True
    keep_windows: bool = False
    threads: int | None = 1
    origin: str = "t0"
    max_samples: int = DEFAULT_MAX_SAMPLES
    diffraction: bool = False
    pixel_pitch_mm: float | None = None


def auto_spp(shape, particles: int = AUTO_PARTICLES) -> int:
    """spp that gives at least ``particles`` samples per window on a window film of ``shape``:
    a power of two (so it splits into equal passes, one compiled kernel)."""
    n = particles / (int(shape[0]) * int(shape[1]))
    return 1 if n <= 1 else 2 ** math.ceil(math.log2(n))


def _is_int_in(x, lo: int, hi: int) -> bool:
    try:
        return not isinstance(x, bool) and float(x).is_integer() and lo <= int(x) <= hi
    except (TypeError, ValueError, OverflowError):
        return False


def check_spp(spp) -> int:
    """spp (samples per film pixel and window) as an int, or ParameterError."""
    if not _is_int_in(spp, 1, MAX_SPP):
        raise ParameterError(f"`spp` must be an integer in [1, {MAX_SPP}], got {spp!r}")
    return int(spp)


def check_seed(seed) -> int:
    """A seed in [0, 2^32) as an int, or ParameterError."""
    if not _is_int_in(seed, 0, 2**32 - 1):
        raise ParameterError(f"`seed` must be an integer in [0, 2^32), got {seed!r}")
    return int(seed)


@dataclass(frozen=True)
class RenderRequest:
    """A checked render request: everything but the rendering (see :func:`plan_render`)."""

    setup: ModeSetup
    model: np.ndarray
    shape: tuple[int, int]
    centre: float
    film: Film
    spp: int
    seed: int
    velocity: float


def _shape2(size) -> tuple[int, int]:
    return (int(size), int(size)) if np.isscalar(size) else tuple(int(v) for v in size)


def check_request(
    design: CameraDesign,
    spp: int | None = None,
    seed: int = 0,
    film: str = "window",
    integrator: str = "ptracer",
    origin: str = "t0",
) -> tuple[int | None, int]:
    """The cheap checks of :func:`plan_render` (before any PSF is computed): returns
    (spp, seed) as ints (spp None stays None)."""
    seed = check_seed(seed)
    if spp is not None:
        spp = check_spp(spp)
    if integrator not in INTEGRATORS:
        raise ParameterError(
            f"integrator must be one of {', '.join(INTEGRATORS)}, got {integrator!r}"
        )
    if film not in FILM_MODES:
        raise ParameterError(f"film must be one of {', '.join(FILM_MODES)}, got {film!r}")
    if origin not in ("t0", "pinhole"):
        raise ParameterError(f"origin must be 't0' or 'pinhole', got {origin!r}")
    Z = check_positive("depth (object_depth_mm)", design.object_depth_mm, "mm")
    if not MIN_DEPTH_MM <= Z <= MAX_DEPTH_MM:
        raise ParameterError(
            f"depth must be in [{MIN_DEPTH_MM:g}, {MAX_DEPTH_MM:g}] mm to render, got {Z!r}"
        )
    return spp, seed


def plan_render(
    design: CameraDesign, spec: PSFSpec | None = None, model: np.ndarray | None = None
) -> RenderRequest:
    """Check a render (raises :class:`ParameterError` naming the field of ``spec`` and its
    range) and compute the analytic kernel, the film and the placement; renders nothing.
    ``model``: the analytic kernel if already computed (``design_psf(design, spec.mode,
    spec.velocity, spec.size, origin=spec.origin)``), to save its computation."""

    spec = PSFSpec() if spec is None else spec
    velocity = check_finite("velocity (px/ms)", spec.velocity)
    spp, seed = check_request(design, spec.spp, spec.seed, spec.film, spec.integrator, spec.origin)
    setup = mode_setup(design, spec.mode)
    size = spec.size
    if model is None:
        model = design_psf(design, spec.mode, velocity, size, origin=spec.origin)
    elif size is not None and np.shape(model) != _shape2(size):
        raise ParameterError(f"model kernel {np.shape(model)} does not match size {size!r}")
    if spec.pixel_pitch_mm is not None:
        check_positive("pixel_pitch_mm", spec.pixel_pitch_mm, "mm")
    if spec.diffraction:  # the geometric kernel, diffracted as the rays will be
        import mitsuba as mi

        n = channels(mi.variant() or "")
        sensor_params(design, spec.mode, n, spec.pixel_pitch_mm)  # refuses pinholes, bitmaps

        def build(cam, f, fine):  # the same kernel on pixels f times finer
            return design_psf(cam, spec.mode, velocity * f, fine, origin=spec.origin)

        model = diffracted_model(build, design, spec.mode, model.shape, n, spec.pixel_pitch_mm,
                                 velocity, spec.origin)  # fmt: skip
    shape = model.shape
    centre = setup.origin_px if spec.origin == "t0" else 0.0
    filmset = film_for(design, centre, shape, spec.film)
    if spp is None:
        spp = auto_spp(shape) if spec.film == "window" else 1
    return RenderRequest(setup, model, shape, centre, filmset, spp, seed, velocity)


def check_render_budget(
    req: RenderRequest,
    integrator: str = "ptracer",
    per_window: bool = True,
    max_samples: int = DEFAULT_MAX_SAMPLES,
) -> int:
    """Refuse a render of more than ``max_samples`` particles (or camera rays), before any.

    Parameters
    ----------
    req : RenderRequest
        What :func:`plan_render` returned.
    integrator : str
        ``ptracer`` traces spp x the *whole* film's pixels, even for a crop.
    per_window : bool
        Whether each open window is rendered apart (spp each) or the exposure at once.
    max_samples : int
        The limit (``--max-samples``).

    Returns
    -------
    int
        The render's samples.

    Raises
    ------
    ParameterError
        Naming ``max_samples``, if the render needs more.
    """
    pixels = req.film.sample_pixels(integrator)
    windows = int(req.setup.open.sum()) if per_window else 1
    hint = ""
    if req.film.mode == "crop" and integrator == "ptracer":
        hint = f"; ptracer traces the whole {req.film.width}x{req.film.height} film for a crop"
    check_count(
        f"samples of this PSF render (spp {req.spp} x {pixels} film px x {windows} windows)",
        req.spp * pixels * windows,
        max_samples,
        "max_samples",
        hint,
    )
    return req.spp * pixels * windows
