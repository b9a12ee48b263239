"""Ray-traced PSFs of a :class:`~pacam_render.model.camera.CameraDesign`, registered with the
analytic ones of :mod:`pacam_render.psf` (issue 6).

What is rendered
----------------
A tiny one-sided disk emitter (:func:`pacam_render.scenes.psf_scene`) on black, seen by the
``programmable_aperture`` sensor, traced with ``ptracer`` (``max_depth`` 2; ``path`` with
``max_depth`` 2 is offered for comparisons), a box pixel filter, float32, one channel. Every
pattern window of the exposure is rendered separately (the sensor's ``time_window``); the windows
tile the exposure, so their sum is the PSF, and each window's centroid gives the measured image
trajectory over the patterns, from which a_i (Eq. 18) is fitted.

Registration
------------
The kernel is an odd-sized (h, w) array whose centre pixel (h//2, w//2) is centred on where the
point images at mid-exposure t = 0, exactly as :func:`pacam_render.psf.design_psf` draws it
(for the coded modes: where the continuous parabola's vertex is; the aperture would be at
X_a(0) = -(R_max - R), so on the prototype film that is column W/2 - beta_px (R_max - R)).
Two film set-ups give the same registration:

* ``film="window"`` (default): a film of exactly the kernel's size whose field of view gives the
  prototype's focal length in pixels, (W/2)/tan(fov/2). Its centre is a pixel centre (odd
  size); the source is displaced sideways in the scene by the t = 0 image offset, so its t = 0
  image lands there. The thin lens is shift-invariant (Eq. 8's parallax term does not depend
  on the point's position), so this is the prototype film's PSF, moved by a few pixels.
* ``film="crop"``: a crop window (``crop_width`` ...) of the full 1280x960 prototype film; the
  source sits on the optical axis, displaced by the sub-pixel amounts that put its t = 0 image
  on a pixel centre.

Why "window" is the default: Mitsuba 3.9.1's particle tracer traces ``spp`` x the *full* film's
pixel count of particles whatever the crop (read in ``integrator.cpp``, ``AdjointIntegrator``:
``samples_per_pass = film_size.x * film_size.y * spp``; measured: a 47x47 crop of the
1280x960 film costs as much as the whole film). So a crop does not save time with ``ptracer``;
the window film does. ``spp`` keeps Mitsuba's meaning in both: particles (or camera rays for
``path``) per film pixel, per window.

Float32 accumulation
--------------------
``ptracer`` splats with float32 atomics. Millions of equal-weight particles added to one pixel
in float32 drift: a 2 px pillbox rendered with 2^24 particles in one call summed 0.25 % high,
one of radius 0.6 px 3.5 %; 16 windows of 64 spp of the 1280x960 film (79M particles per call)
gave a coded PSF with an L1 error of 0.010 against a noise floor of 0.0002. Each window is
therefore rendered in passes sized so that the brightest pixel expects at most
:data:`ADDS_PER_PIXEL` particles (drift ~1e-4), with their own seeds, summed in float64.

Moving source
-------------
Mitsuba 3 moves no geometry with ray time. For one point source on black (everything that moves
shares one velocity), moving the whole scene by v (t - t_mid) is exact and continuous in a single
render: this module's sensor ``pacam_psf_camera`` is ``programmable_aperture`` plus that one
rigid velocity (:meth:`set_scene_velocity`): camera rays start at o - v tau and particle-tracer
connections see the scene point at p + v tau, tau = t - t_mid the ray's (window-mapped) time.
The plugin file itself is unchanged; the subclass overrides two of its methods.

Source size
-----------
The emitter is a disc of radius ``source_radius_px`` (default 0.02 px in the image, instead of
psf_scene's 0.25 px). Its image is convolved with the PSF; after pixel integration the change is
second order in the radius (:func:`source_blur_l1`: 1.1e-3 of L1 for a 0.6 px pillbox, at most
4e-4 for r >= 1 px; 0.25 px would give 0.18 and 0.013 for r = 0.6 and 2 px). The particle
tracer's noise does not depend on the emitter's size (its power is fixed), so the small source
costs nothing. The camera-ray ``path`` tracer must hit the source: use a larger one there.

Determinism: the same seed gives the same particles, but with several Dr.Jit threads the float32
atomic adds run in a thread-dependent order (6e-6 relative differences seen between two runs).
Renders therefore use one thread by default (``threads=1``): the same seed then gives a
bit-identical kernel, and on this 2-core machine it was no slower (ptracer's atomics contend).

Units: mm, ms, px; velocities px/ms in the image (+ to the right), accelerations px/ms^2.
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..limits import DEFAULT_MAX_SAMPLES, check_count
from ..model import schedule as sch
from ..model.camera import MIN_FOCUS_MM, CameraDesign
from ..model.modes import (
    MODES,
    MODES_WITH_PSF,
    held_offsets_px,
    image_acceleration,
    mode_exposure_ms,
    sensor_params,
    t0_offset_px,
)
from ..render.registry import PSF_PLUGIN_NAME, ensure_registered, sensor_dict
from ..restore.metrics import fit_acceleration, kernel_centroid, rel_l1
from ..scenes import image_to_scene_velocity, psf_scene
from .checkpoint import deferred_signals

DEFAULT_SOURCE_RADIUS_PX = 0.02
"""Radius of the emitter's image, px: small enough that it does not show (see source_blur_l1)."""
ADDS_PER_PIXEL = 1 << 15
"""Render calls are sized so that the brightest pixel expects at most this many particles: it
bounds the float32 drift (2^16 equal adds to one pixel drifted 4.5e-4, 2^14 1e-4)."""
PARTICLES_PER_PASS = 1 << 22
"""At most this many particles (or camera rays) per render call (memory)."""
AUTO_PARTICLES = 1 << 18
"""``spp=None``: enough samples per pixel for about this many particles per window."""
MAX_SPP = 1 << 20
RENDER_MODES = MODES_WITH_PSF
INTEGRATORS = ("ptracer", "path")
FILM_MODES = ("window", "crop")
NEAR_CLIP_MM = 1.0
FAR_CLIP_MM = 1.0e7
MIN_DEPTH_MM, MAX_DEPTH_MM = MIN_FOCUS_MM, 1.0e6


# ------------------------------------------------------------------------------------------
# Modes: sensor schedule, windows, where the kernel's origin is
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ModeSetup:
    """How a :func:`~pacam_render.psf.design_psf` mode is rendered.

    ``sensor``: ``configure`` arguments; ``exposure_ms``: the shutter interval [0, exposure];
    ``edges_ms``: window edges (sensor time); ``open``: whether each window lets light in;
    ``origin_px``: film-column offset of the t = 0 image from the point's pinhole image;
    ``a_i``: the model's image acceleration (px/ms^2); ``discrete``: positions held per window;
    ``held_px``: a designed schedule's held (u, v) per window, px from the t = 0 image (None:
    the parabola's a_i t_k^2 / 2 on row 0).
    """

    mode: str
    sensor: dict
    exposure_ms: float
    edges_ms: np.ndarray
    open: np.ndarray
    origin_px: float
    a_i: float
    discrete: bool
    held_px: np.ndarray | None = None

    def held_u_px(self, tm: np.ndarray) -> np.ndarray:
        """Where each discrete window (mid-times tm, ms) holds the still point, columns px."""
        return 0.5 * self.a_i * tm**2 if self.held_px is None else self.held_px[:, 0]

    @property
    def T_ms(self) -> float:
        return 0.5 * self.exposure_ms


def mode_setup(design: CameraDesign, mode: str = "coded") -> ModeSetup:
    """Sensor configuration and time windows that render ``design_psf(design, mode, ...)``.

    Everything but the windows comes from :mod:`pacam_render.model.modes`: the schedule,
    the exposure, a_i and the t = 0 image offset. The design is rendered as given (a PSF
    request names its camera); captures first apply the mode's refocus and opening.
    """
    if mode not in RENDER_MODES:
        raise ParameterError(f"mode must be one of {', '.join(RENDER_MODES)}, got {mode!r}")
    m = MODES[mode]
    sensor = sensor_params(design, mode)
    exposure = mode_exposure_ms(design, mode)
    n, is_open = design.n_patterns, None
    if m.schedule == "flutter":
        is_open = sch.flutter_code().astype(bool)
        n = len(is_open)
    return ModeSetup(
        mode=mode,
        sensor=sensor,
        exposure_ms=exposure,
        edges_ms=np.linspace(0.0, exposure, n + 1),
        open=np.ones(n, dtype=bool) if is_open is None else is_open,
        origin_px=t0_offset_px(design, mode),
        a_i=image_acceleration(design, mode),
        discrete=mode == "flutter" or (m.schedule == "parabolic" and not m.continuous),
        held_px=held_offsets_px(design) if design.designed and mode == "coded" else None,
    )


def model_window_centroids(setup: ModeSetup, velocity: float) -> np.ndarray:
    """Model's centroid (px from the kernel origin) of each window: the mean of x(t) over it.

    Discrete patterns hold a_i t_k^2/2 during window k; continuous ones follow a_i t^2/2.
    """
    T = setup.T_ms
    e = setup.edges_ms - T
    t0, t1 = e[:-1], e[1:]
    tm = 0.5 * (t0 + t1)
    if setup.mode == "flutter":
        return velocity * tm
    if setup.discrete:
        return velocity * tm + setup.held_u_px(tm)
    return velocity * tm + 0.5 * setup.a_i * (t1**3 - t0**3) / (3.0 * (t1 - t0))


def model_window_kernels(design: CameraDesign, mode: str, velocity: float, shape) -> list:
    """The model's pixel-integrated kernel of each window (each normalised; None if shut),
    registered like ``design_psf(..., origin="t0")``: the same estimator (pixel centroids)
    applied to these gives the model's own value, free of Monte Carlo noise."""
    from ..psf.analytic import kernel_from_trajectory
    from ..psf.trajectory import Segment

    setup = mode_setup(design, mode)
    s = check_finite("velocity (px/ms)", velocity)
    T = setup.T_ms
    e = setup.edges_ms - T
    r = 0.0 if mode == "levin" else design.r_px
    out = []
    for k in range(len(e) - 1):
        if not setup.open[k]:
            out.append(None)
            continue
        t0, t1 = float(e[k]), float(e[k + 1])
        tm = 0.5 * (t0 + t1)
        if setup.discrete and mode != "flutter":
            u, v = (0.5 * setup.a_i * tm * tm, 0.0) if setup.held_px is None else setup.held_px[k]
            seg = Segment(t0, t1, float(u), s, 0.0, y=float(v))
        else:
            seg = Segment(t0, t1, 0.0, s, setup.a_i)
        out.append(kernel_from_trajectory([seg], r, size=shape))
    return out


# ------------------------------------------------------------------------------------------
# Results
# ------------------------------------------------------------------------------------------
@dataclass
class RenderedPSF:
    """A rendered PSF (float64, sums to 1, registered like the analytic kernel) and its windows.

    Window arrays (one entry per window): paper times ``t_start_ms``/``t_end_ms`` (t = 0 at
    mid-exposure), ``mass`` (fraction of the PSF), measured centroid ``centroid_u_px``
    (columns, + right) and ``centroid_v_px`` (rows, + down) from the kernel origin, and the
    model's ``model_u_px``. Closed windows (flutter) have mass 0 and NaN centroids.
    """

    kernel: np.ndarray
    raw_sum: float
    mode: str
    velocity_px_per_ms: float
    spp: int
    seed: int
    integrator: str
    seconds: float
    particles: int
    passes: int
    film: dict
    source_radius_px: float
    t_start_ms: np.ndarray
    t_end_ms: np.ndarray
    mass: np.ndarray
    centroid_u_px: np.ndarray
    centroid_v_px: np.ndarray
    model_u_px: np.ndarray
    model_a_i: float
    threads: int | None = 1
    origin: str = "t0"
    window_kernels: list | None = field(default=None, repr=False)
    model: np.ndarray | None = field(default=None, repr=False)
    """The analytic kernel (``design_psf``, same size and registration)."""

    @property
    def t_mid_ms(self) -> np.ndarray:
        return 0.5 * (self.t_start_ms + self.t_end_ms)

    @property
    def fitted_a_i(self) -> float:
        """a_i from a least-squares parabola through the window centroids, px/ms^2."""
        return fit_acceleration(self.t_mid_ms, self.centroid_u_px, self.mass)

    @property
    def centroid_px(self) -> tuple[float, float]:
        return kernel_centroid(self.kernel)

    def to_json(self) -> dict:
        """JSON-ready summary with the per-window centroid trajectory."""

        def num(x):
            x = float(x)
            return x if math.isfinite(x) else None

        traj = [
            {
                "window": k,
                "t_start_ms": num(self.t_start_ms[k]),
                "t_end_ms": num(self.t_end_ms[k]),
                "t_mid_ms": num(self.t_mid_ms[k]),
                "mass": num(self.mass[k]),
                "centroid_u_px": num(self.centroid_u_px[k]),
                "centroid_v_px": num(self.centroid_v_px[k]),
                "model_u_px": num(self.model_u_px[k]),
            }
            for k in range(len(self.mass))
        ]
        cu, cv = self.centroid_px
        return {
            "integrator": f"{self.integrator} (max_depth 2)",
            "rfilter": "box",
            "pixel_format": "luminance, float32 (accumulated in float64 over passes)",
            "spp": self.spp,
            "spp_meaning": "Mitsuba spp per window: particles (ptracer) or camera rays (path) "
            "per film pixel; ptracer traces spp x the full film's pixels even with a crop",
            "seed": self.seed,
            "run_time_s": self.seconds,
            "particles": self.particles,
            "render_calls": self.passes,
            "drjit_threads": self.threads,
            "source_radius_px": self.source_radius_px,
            "film": self.film,
            "raw_sum": self.raw_sum,
            "centroid_px": [cu, cv],
            "fitted_a_i_px_per_ms2": num(self.fitted_a_i),
            "model_a_i_px_per_ms2": self.model_a_i,
            "centroid_trajectory": traj,
            "kernel_origin": self.origin,
            "centroid_convention": "px from the kernel's centre pixel (the t = 0 image for "
            "origin t0, the pinhole image for origin pinhole): u + right, v + down; t in ms, "
            "t = 0 at mid-exposure",
        }


def source_blur_l1(r_px: float, source_radius_px: float, rings: int = 4) -> float:
    """L1 change of a pixel-integrated pillbox of radius r_px when convolved with a uniform
    source disc (quadrature over the source: equal-area rings): the source-size effect."""
    from ..psf.analytic import pillbox_psf

    r = check_positive("r_px", r_px, "px")
    rs = float(source_radius_px)
    if rs <= 0:
        return 0.0
    n = 2 * math.ceil(r + rs + 0.5) + 1
    base = pillbox_psf(r, size=n)
    acc = np.zeros_like(base)
    for i in range(rings):
        rr = rs * math.sqrt((i + 0.5) / rings)
        m = 6 * (i + 1)
        for j in range(m):
            th = 2 * math.pi * (j + 0.5 * i) / m
            acc += pillbox_psf(r, size=n, centre=(rr * math.cos(th), rr * math.sin(th))) / (
                rings * m
            )
    return rel_l1(acc, base)


# ------------------------------------------------------------------------------------------
# Rendering
# ------------------------------------------------------------------------------------------
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
        raise ParameterError(f"spp (--spp) must be an integer in [1, {MAX_SPP}], got {spp!r}")
    return int(spp)


def check_seed(seed) -> int:
    """A seed in [0, 2^32) as an int, or ParameterError."""
    if not _is_int_in(seed, 0, 2**32 - 1):
        raise ParameterError(f"seed (--seed) must be an integer in [0, 2^32), got {seed!r}")
    return int(seed)


def _seed(seed: int, *keys: int) -> int:
    """An independent uint32 Mitsuba seed for (seed, window, pass)."""
    return int(np.random.SeedSequence([seed, *keys]).generate_state(1)[0])


def _spp_per_pass(spp: int, film: _Film, integrator: str, peak: float) -> int:
    """Samples per pixel of one render call: a power of two (few distinct kernels to compile),
    at most ``spp``, with at most PARTICLES_PER_PASS samples and, for ptracer, at most
    ADDS_PER_PIXEL particles expected in the brightest pixel (``peak``: the largest fraction
    of one window's particles that one pixel receives)."""
    pixels = film.sample_pixels(integrator)
    budget = PARTICLES_PER_PASS
    if integrator == "ptracer":
        budget = min(budget, ADDS_PER_PIXEL / max(min(peak, 1.0), 1e-12))
    n = int(budget // pixels)
    n = 2 ** int(math.log2(n)) if n >= 1 else 1
    return max(1, min(spp, n))


@contextmanager
def _threads(n: int | None):
    """Run with n Dr.Jit worker threads (None: leave them), restoring the count afterwards."""
    import drjit as dr

    if n is None:
        yield
        return
    old = dr.thread_count()
    dr.set_thread_count(int(n))
    try:
        yield
    finally:
        dr.set_thread_count(old)


@dataclass
class _Film:
    mode: str
    width: int  # film size (the prototype's for crop)
    height: int
    kernel_shape: tuple[int, int]
    fov_deg: float
    crop_offset: tuple[int, int] | None
    source_xy_mm: tuple[float, float]
    origin_film_px: tuple[float, float]

    def mitsuba(self) -> dict:
        d = {
            "type": "hdrfilm",
            "width": self.width,
            "height": self.height,
            "rfilter": {"type": "box"},
            "pixel_format": "luminance",
            "component_format": "float32",
        }
        if self.crop_offset is not None:
            h, w = self.kernel_shape
            d.update(
                crop_width=w,
                crop_height=h,
                crop_offset_x=self.crop_offset[0],
                crop_offset_y=self.crop_offset[1],
            )
        return d

    def sample_pixels(self, integrator: str) -> int:
        """Pixels that Mitsuba multiplies by spp: the full film's for ptracer (even with a
        crop), the crop's for camera-ray integrators."""
        if integrator == "ptracer":
            return self.width * self.height
        h, w = self.kernel_shape
        return h * w

    def key(self, integrator: str, exposure_ms: float) -> tuple:
        return (
            integrator,
            self.mode,
            self.width,
            self.height,
            self.kernel_shape,
            self.crop_offset,
            round(self.fov_deg, 12),
            exposure_ms,
        )

    def describe(self, design: CameraDesign) -> dict:
        h, w = self.kernel_shape
        out = {
            "mode": self.mode,
            "width_px": self.width,
            "height_px": self.height,
            "fov_deg": self.fov_deg,
            "focal_length_px": design.focal_length_px,
            "kernel_origin_on_film_px": list(self.origin_film_px),
            "source_offset_mm": list(self.source_xy_mm),
        }
        if self.crop_offset is not None:
            out["crop"] = {
                "offset_x": self.crop_offset[0],
                "offset_y": self.crop_offset[1],
                "width": w,
                "height": h,
            }
            out["registration"] = (
                f"kernel pixel (i, j) is film pixel ({self.crop_offset[1]} + i, "
                f"{self.crop_offset[0]} + j) of the {self.width}x{self.height} prototype film"
            )
        else:
            out["registration"] = (
                "a film of the kernel's size with the prototype's focal length in px; the "
                "source is displaced so that its t = 0 image is the centre of pixel (h//2, w//2)"
            )
        return out


def _film_for(design: CameraDesign, centre_px: float, shape, film_mode: str) -> _Film:
    """Film and source placement that put image position ``centre_px`` (film columns from the
    point's pinhole image, at mid-exposure) on the centre of kernel pixel (h//2, w//2)."""
    h, w = shape
    if h % 2 == 0 or w % 2 == 0:
        raise ParameterError(f"kernel size must be odd (h, w), got {shape}")
    W, H = design.width_px, design.height_px
    if h > H - 1 or w > W - 1:
        raise ParameterError(
            f"a rendered PSF must fit the {W}x{H} film: kernel side at most {W - 1} x "
            f"{H - 1} px (odd), got {w} x {h}; lower --size, --velocity or the defocus"
        )
    Z, f = design.object_depth_mm, design.focal_length_px
    if film_mode == "window":
        # film of the kernel's size, same focal length in px; centre (w/2, h/2) = centre of
        # pixel (h//2, w//2). Pinhole image u = w/2 - f X / Z; the centre at u + centre_px.
        fov = 2.0 * math.degrees(math.atan(0.5 * w / f))
        x_mm = centre_px * Z / f
        return _Film("window", w, h, (h, w), fov, None, (x_mm, 0.0), (0.5 * W, 0.5 * H))
    if film_mode != "crop":
        raise ParameterError(f"film must be one of {', '.join(FILM_MODES)}, got {film_mode!r}")
    u_nat = 0.5 * W + centre_px  # where the kernel centre falls for an on-axis point
    j0, i0 = math.floor(u_nat), math.floor(0.5 * H)
    x_mm = (u_nat - (j0 + 0.5)) * Z / f  # u = W/2 - f X/Z + centre_px = j0 + 1/2
    y_mm = (0.5 * H - (i0 + 0.5)) * Z / f  # v = H/2 - f Y/Z = i0 + 1/2
    ox, oy = j0 - w // 2, i0 - h // 2
    if ox < 0 or oy < 0 or ox + w > W or oy + h > H:
        raise ParameterError(
            f"the {w}x{h} kernel around film pixel ({j0}, {i0}) leaves the {W}x{H} film; "
            f"lower --size or use film='window'"
        )
    fov = design.fov_deg
    return _Film("crop", W, H, (h, w), fov, (ox, oy), (x_mm, y_mm), (j0 + 0.5, i0 + 0.5))


@dataclass(frozen=True)
class RenderRequest:
    """A checked render request: everything but the rendering (see :func:`plan_render`)."""

    setup: ModeSetup
    model: np.ndarray
    shape: tuple[int, int]
    centre: float
    film: _Film
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
    design: CameraDesign,
    mode: str = "coded",
    velocity: float = 0.0,
    size=None,
    spp: int | None = None,
    seed: int = 0,
    film: str = "window",
    integrator: str = "ptracer",
    origin: str = "t0",
    model: np.ndarray | None = None,
) -> RenderRequest:
    """Check a render request (raises :class:`ParameterError` naming the parameter and its
    range) and compute the analytic kernel, the film and the placement; renders nothing.
    ``model``: the analytic kernel if already computed (``design_psf(design, mode, velocity,
    size, origin=origin)``), to save its computation."""
    from ..psf.analytic import design_psf

    velocity = check_finite("velocity (px/ms)", velocity)
    spp, seed = check_request(design, spp, seed, film, integrator, origin)
    setup = mode_setup(design, mode)
    if model is None:
        model = design_psf(design, mode, velocity, size, origin=origin)
    elif size is not None and np.shape(model) != _shape2(size):
        raise ParameterError(f"model kernel {np.shape(model)} does not match size {size!r}")
    shape = model.shape
    centre = setup.origin_px if origin == "t0" else 0.0
    filmset = _film_for(design, centre, shape, film)
    if spp is None:
        spp = auto_spp(shape) if film == "window" else 1
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


class PSFRenderer:
    """Renders PSFs, reusing loaded scenes (and so Dr.Jit's compiled kernels) across calls.

    A scene is loaded per film size, exposure and integrator; depth, opening, focus, schedule,
    velocity and source move through opaque parameters, so sweeping them never recompiles.
    """

    def __init__(self, source_radius_px: float = DEFAULT_SOURCE_RADIUS_PX):
        ensure_registered()
        self.source_radius_px = check_positive("source_radius_px", source_radius_px, "px")
        self._scenes: dict[tuple, tuple] = {}

    def _scene(self, design: CameraDesign, setup: ModeSetup, film: _Film, integrator: str):
        import mitsuba as mi

        key = film.key(integrator, setup.exposure_ms)
        if key not in self._scenes:
            Z = design.object_depth_mm
            desc = psf_scene(Z, 0.0, camera=design)
            sensor = sensor_dict(
                fov=film.fov_deg,
                shutter_open=0.0,
                shutter_close=setup.exposure_ms,
                near_clip=NEAR_CLIP_MM,
                far_clip=FAR_CLIP_MM,
                film=film.mitsuba(),
                **setup.sensor,
            )
            sensor["type"] = PSF_PLUGIN_NAME
            integ = {"type": integrator, "max_depth": 2}
            scene = desc.load(sensor=sensor, integrator=integ)
            params = mi.traverse(scene)
            params.keep(["psf_disk.to_world", "psf_disk.emitter.radiance.value"])
            self._scenes[key] = (scene, params)
        return self._scenes[key]

    def _place(self, design, setup, film, velocity, scene, params):
        import mitsuba as mi

        Z, f = design.object_depth_mm, design.focal_length_px
        rs_px = self.source_radius_px
        rs = rs_px * Z / f
        x, y = film.source_xy_mm
        m = [[-rs, 0.0, 0.0, x], [0.0, rs, 0.0, y], [0.0, 0.0, -1.0, Z], [0.0, 0.0, 0.0, 1.0]]
        params["psf_disk.to_world"] = type(params["psf_disk.to_world"])(m)
        params["psf_disk.emitter.radiance.value"] = mi.Color3f(1.0 / (math.pi * rs_px**2))
        params.update()
        sensor = scene.sensors()[0]
        sensor.configure(time_window=None, **setup.sensor)
        sensor.set_scene_velocity(image_to_scene_velocity(velocity, Z, design))
        return sensor

    def render(
        self,
        design: CameraDesign,
        mode: str = "coded",
        velocity: float = 0.0,
        *,
        size=None,
        spp: int | None = None,
        seed: int = 0,
        film: str = "window",
        integrator: str = "ptracer",
        per_window: bool = True,
        keep_windows: bool = False,
        threads: int | None = 1,
        origin: str = "t0",
        model: np.ndarray | None = None,
        progress: bool = False,
        max_samples: int = DEFAULT_MAX_SAMPLES,
    ) -> RenderedPSF:
        """Render ``design_psf(design, mode, velocity, size)`` (see the module docstring).

        ``size``: odd int or (h, w), default the analytic kernel's automatic size. ``spp``:
        Mitsuba's samples per film pixel for each window (None: :func:`auto_spp`, about
        2^18 particles per window on the kernel-sized film). ``per_window=False`` renders the
        whole exposure at once (no trajectory). ``keep_windows`` keeps each window's image.
        ``threads``: Dr.Jit worker threads while rendering; 1 (default) makes the same seed
        give bit-identical kernels (ptracer's float32 atomic adds otherwise run in a
        thread-dependent order: 6e-6 relative differences seen with 2), None keeps the
        current count. ``origin``: what the kernel's centre pixel stands for, as in
        :func:`~pacam_render.psf.design_psf`: ``"t0"`` (the t = 0 image) or ``"pinhole"``.
        ``model``: that analytic kernel, if already computed (saves its computation).
        ``max_samples``: refuse a render of more particles (:func:`check_render_budget`).
        A SIGINT or SIGTERM during the render raises KeyboardInterrupt after the render call
        under way; its partial image is never used.
        """
        req = plan_render(design, mode, velocity, size, spp, seed, film, integrator, origin, model)
        check_render_budget(req, integrator, per_window, max_samples)
        scene, params = self._scene(design, req.setup, req.film, integrator)
        sensor = self._place(design, req.setup, req.film, req.velocity, scene, params)
        windows, is_open = _windows(req.setup, per_window)
        peak = req.model.max() * int(is_open.sum())
        spp_pass = _spp_per_pass(req.spp, req.film, integrator, peak)
        plan = _pass_plan(req.spp, spp_pass, is_open)
        t0 = time.perf_counter()
        with _threads(threads):
            images = self._render_passes(
                scene, sensor, req, windows, plan, per_window, f"render {mode} PSF", progress
            )
        seconds = time.perf_counter() - t0
        return self._result(
            req, mode, integrator, windows, is_open, images, plan, per_window, keep_windows,
            seconds=seconds, threads=threads, origin=origin, design=design,
        )  # fmt: skip

    def _render_passes(self, scene, sensor, req, windows, plan, per_window, desc, progress):
        """Render every (window, pass) of ``plan``; returns the windows' images (float64)."""
        import mitsuba as mi

        h, w = req.shape
        images = [np.zeros((h, w)) for _ in windows]
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(plan), desc=desc, unit="pass", leave=False)
        current = None
        integ = scene.integrator()
        try:
            with deferred_signals() as flag:
                for k, p, n in plan:
                    if current != k:
                        sensor.configure(time_window=None if not per_window else windows[k])
                        current = k
                    img = _render_call(mi, scene, n, _seed(req.seed, k, p))
                    # Mitsuba's own SIGINT handler cuts a render short and returns it: unusable
                    if flag["signal"] is not None or integ.should_stop():
                        raise KeyboardInterrupt
                    images[k] += np.array(img, dtype=np.float64).reshape(h, w) * (n / req.spp)
                    if bar is not None:
                        bar.update()
        finally:
            if bar is not None:
                bar.close()
            sensor.configure(time_window=None)
        return images

    def _result(self, req, mode, integrator, windows, is_open, images, plan, per_window,
                keep_windows, *, seconds, threads, origin, design) -> RenderedPSF:  # fmt: skip
        """Normalise the windows' images into a :class:`RenderedPSF` with its trajectory."""
        setup = req.setup
        total = sum(images)
        raw = float(total.sum())
        if not raw > 0:
            raise ParameterError(
                "the rendered PSF is black: the source is outside the view (check depth and size)"
            )
        T = setup.T_ms
        mass = np.array([im.sum() for im in images]) / raw
        cents = np.array(
            [kernel_centroid(im) if im.sum() > 0 else (np.nan, np.nan) for im in images]
        )
        if per_window:
            model_u = model_window_centroids(setup, req.velocity) + (setup.origin_px - req.centre)
            model_u = np.where(is_open, model_u, np.nan)
        else:
            model_u = np.array([np.nan])
        return RenderedPSF(
            kernel=total / raw,
            raw_sum=raw,
            mode=mode,
            velocity_px_per_ms=req.velocity,
            spp=req.spp,
            seed=req.seed,
            integrator=integrator,
            seconds=seconds,
            particles=int(sum(n for *_, n in plan) * req.film.sample_pixels(integrator)),
            threads=threads,
            passes=len(plan),
            film=req.film.describe(design),
            source_radius_px=self.source_radius_px,
            t_start_ms=np.array([a for a, _ in windows]) - T,
            t_end_ms=np.array([b for _, b in windows]) - T,
            mass=mass,
            centroid_u_px=cents[:, 0],
            centroid_v_px=cents[:, 1],
            model_u_px=model_u,
            model_a_i=setup.a_i,
            origin=origin,
            window_kernels=[im / raw for im in images] if keep_windows else None,
            model=req.model,
        )


def _render_call(mi, scene, spp: int, seed: int):
    """``mi.render``; a KeyboardInterrupt that Dr.Jit wrapped in a RuntimeError (a second
    Ctrl-C inside the render) is raised as itself."""
    try:
        return mi.render(scene, spp=spp, seed=seed)
    except RuntimeError as exc:
        if isinstance(exc.__cause__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise


def _windows(setup: ModeSetup, per_window: bool):
    """The time windows to render (sensor ms) and whether each lets light in."""
    edges = setup.edges_ms
    if not per_window:
        return [(edges[0], edges[-1])], np.array([True])
    return [(edges[k], edges[k + 1]) for k in range(len(edges) - 1)], setup.open


def _pass_plan(spp: int, spp_pass: int, is_open: np.ndarray) -> list[tuple[int, int, int]]:
    """(window, pass, samples) for every render call: each open window gets ``spp`` in passes
    of at most ``spp_pass``."""
    plan = []
    for k in np.flatnonzero(is_open):
        left, p = spp, 0
        while left > 0:
            n = min(spp_pass, left)
            plan.append((int(k), p, n))
            left -= n
            p += 1
    return plan


_DEFAULT: PSFRenderer | None = None


def render_psf(design: CameraDesign, mode: str = "coded", velocity: float = 0.0, **kw):
    """:meth:`PSFRenderer.render` on a shared renderer (its scenes are reused)."""
    global _DEFAULT
    radius = kw.pop("source_radius_px", DEFAULT_SOURCE_RADIUS_PX)
    if _DEFAULT is None or _DEFAULT.source_radius_px != radius:
        _DEFAULT = PSFRenderer(radius)
    return _DEFAULT.render(design, mode, velocity, **kw)
