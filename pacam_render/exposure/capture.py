"""Captures: a scene rendered through the programmable-aperture camera over a whole exposure.

Exposure integration. A static scene is one render: each ray's time selects the pattern in the
sensor, so there is no loop and no geometry update. A moving scene is split at the pattern
boundaries, and each pattern window into ``m`` time steps, so that nothing moves more than
``max_step_px`` (default 0.5 px) between steps: m = ceil(v_max dt / max_step_px), v_max the
fastest image speed of any moving shape. Each step moves the geometry to its mid-time (one BVH
rebuild) and renders only its own time window (the sensor's ``time_window``: windows that tile
the exposure sum to the full image). The spp budget is shared among the steps in proportion
to their duration, at least 1 each, so the total stays the request unless there are more steps
than samples. Every step has its own seed, so an interrupted capture resumes from the steps
already on disk and gives the same image as an uninterrupted run.

Units. Pixel values are Mitsuba radiance x (open area / full aperture) x (exposure / 45 ms):
a white diffuse surface seen through the full F2.8 aperture for 45 ms reads about its
reflectance. So a capture is proportional to the light it collects, and captures of different
modes compare directly (``light_factor`` in the JSON is that scale for each mode).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import signal
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError, check_positive
from ..io.outputs import write_json
from ..limits import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_MAX_STEPS,
    PacamWarning,
    check_count,
    check_memory,
)
from ..model import paper
from ..model.camera import CameraDesign, preset
from ..model.modes import MODES as MODE_TABLE
from ..model.modes import capture_camera, mode, sensor_params
from .checkpoint import deferred_signals
from .record import CaptureRecord
from .truth import TRUTH_LAYERS

MODES = tuple(MODE_TABLE)
REFERENCE_EXPOSURE_MS = paper.EXPOSURE_MS
"""Pixel values are scaled to this exposure: a capture's brightness is proportional to the
light it collects, and every mode compares directly."""
PARTIAL = ".partial"


@dataclass(frozen=True)
class CaptureSpec:
    """What to capture. Sizes in px, ``max_step_px`` in px of motion between time steps.

    ``width`` and ``height`` are the sensor's resolution: below the preset's (1280x960 for the
    prototype) the sensor has fewer, larger pixels, and every px quantity (r, a_i, speeds)
    shrinks with it. ``crop`` = (x, y, w, h) renders only that window of the sensor, in its
    pixels (Mitsuba's film crop): the optics stay those of the whole sensor, so a crop of the
    full-resolution sensor is the prototype's camera at its real pixel scale.
    """

    scene: str = "train"
    mode: str = "coded"
    width: int = 320
    height: int = 240
    spp: int = 64
    seed: int = 0
    max_step_px: float = 0.5
    per_pattern: bool = False
    preset: str = "prototype"
    cover_px_per_ms: float | None = None
    crop: tuple[int, int, int, int] | None = None
    f_number: float | None = None
    r_px: float | None = None
    object_depth_mm: float | None = None
    schedule: str | None = None

    def __post_init__(self) -> None:
        mode(self.mode)  # raises, listing the valid modes
        if self.crop is not None:
            object.__setattr__(self, "crop", check_crop(self.crop, self.width, self.height))
        for k, lo in (("width", 2), ("height", 2), ("spp", 1)):
            v = getattr(self, k)
            if not isinstance(v, (int, np.integer)) or v < lo:
                raise ParameterError(f"{k} must be an integer >= {lo}, got {v!r}")
        if not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**31:
            raise ParameterError(f"seed must be an integer in [0, 2^31), got {self.seed!r}")
        check_positive("max_step_px", self.max_step_px, "px")
        if self.cover_px_per_ms is not None:
            check_positive("cover_px_per_ms", self.cover_px_per_ms, "px/ms")
        if self.object_depth_mm is not None:
            check_positive("object_depth_mm", self.object_depth_mm, "mm")
        if (self.f_number is not None or self.r_px is not None) and self.cover_px_per_ms is None:
            raise ParameterError("f_number and r_px size a covering design: they need --cover")
        if self.schedule is not None and self.cover_px_per_ms is not None:
            raise ParameterError("give --cover or --schedule, not both: each sets the design")

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the rendered image, px: the crop's, or the whole sensor's."""
        return (self.crop[2], self.crop[3]) if self.crop else (self.width, self.height)

    def key(self) -> str:
        """A hash of everything that changes the image (for resuming).

        Returns
        -------
        str
            The first 16 hex digits of the SHA-256 of the spec's fields as sorted JSON.
        """
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()[:16]


def check_crop(crop, width: int, height: int) -> tuple[int, int, int, int]:
    """(x, y, w, h) as ints inside a width x height sensor, or ParameterError."""
    try:
        x, y, w, h = (int(v) for v in crop)
        ok = all(int(v) == v for v in crop)
    except (TypeError, ValueError):
        ok = False
    if not ok or w < 2 or h < 2 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise ParameterError(
            f"--crop must be X,Y,W,H: integers with W, H >= 2 and the window inside the "
            f"{width}x{height} sensor (X + W <= {width}, Y + H <= {height}), got {crop!r}"
        )
    return x, y, w, h


def parse_crop(text: str) -> tuple[int, int, int, int]:
    """``"X,Y,W,H"`` (the ``--crop`` flag) as four ints, or ParameterError."""
    parts = text.split(",")
    try:
        if len(parts) != 4:
            raise ValueError
        return tuple(int(p) for p in parts)  # type: ignore[return-value]
    except ValueError:
        raise ParameterError(f"--crop must be X,Y,W,H (four integers), got {text!r}") from None


def capture_design(spec: CaptureSpec) -> CameraDesign:
    """The preset's optics at the capture's resolution (pixel quantities scale with width).

    With ``cover_px_per_ms`` (a speed in the preset's own pixels), the design solver first
    picks the defocus that makes that speed motion-invariant at the preset's F-number, or at
    ``f_number``, or with the defocus radius ``r_px`` (preset px). ``object_depth_mm`` is the
    depth the design is made for (default the preset's: 500 mm for the prototype).

    Parameters
    ----------
    spec : CaptureSpec
        Uses ``preset``, ``cover_px_per_ms`` (px/ms) and ``width`` and ``height`` (px).

    Returns
    -------
    CameraDesign
        The coded design, with ``width_px = spec.width`` and ``height_px = spec.height``.

    Raises
    ------
    ParameterError
        If the preset is unknown, or the solver cannot cover the speed (it names the limit).

    Notes
    -----
    The solver (:func:`~pacam_render.model.design.solve`) makes the invariant range
    |s| <= |a_i| T cover the speed, with a_i = beta a_a (Eq. 18) and the defocus radius
    r = |beta| R (Eq. 12), so |a_i| = 4 r (R_max / R - 1) / T^2; the exposure is 2T.
    """
    depth = {} if spec.object_depth_mm is None else {"object_depth_mm": spec.object_depth_mm}
    base = preset(spec.preset, **depth)
    if spec.cover_px_per_ms is not None:
        from ..model.design import solve

        base = solve(spec.cover_px_per_ms, f_number=spec.f_number, r_px=spec.r_px, base=base)
    if spec.schedule is not None:
        from ..model.schedule_file import apply_schedule, read_schedule

        sched = read_schedule(spec.schedule)
        if spec.object_depth_mm is None and "object_depth_mm" in sched:
            base = base.with_(object_depth_mm=sched["object_depth_mm"])
        base = apply_schedule(base, sched, spec.schedule)
    return base.with_(width_px=spec.width, height_px=spec.height)


def mode_camera(design: CameraDesign, mode: str) -> tuple[CameraDesign, dict]:
    """The camera a mode uses (for its analytic PSF) and the sensor's schedule parameters,
    both from the table of :mod:`pacam_render.model.modes`.

    Parameters
    ----------
    design : CameraDesign
        The coded design (:func:`capture_design`).
    mode : str
        A capture mode, one of :data:`MODES`.

    Returns
    -------
    cam : CameraDesign
        :func:`~pacam_render.model.modes.capture_camera`: the design with the mode's focus,
        opening and exposure; its analytic PSF is ``design_psf(cam, mode)``.
    params : dict
        :func:`~pacam_render.model.modes.sensor_params`: the ``programmable_aperture``
        parameters (lengths in mm) that show the mode; empty for ``reference``.

    Raises
    ------
    ParameterError
        If ``mode`` is unknown (the message lists the valid ones), or a mode with a moving
        aperture gets a design without parallax (beta = 0).
    """
    cam = capture_camera(design, mode)
    return cam, sensor_params(cam, mode)


def sensor_entry(spec: CaptureSpec, design: CameraDesign, params: dict, exposure_ms: float):
    """The scene's sensor: programmable_aperture, or a pinhole for the reference.

    Parameters
    ----------
    spec : CaptureSpec
        Uses ``mode``, ``width`` and ``height`` (px) and ``spp``.
    design : CameraDesign
        The mode's camera (its field of view, deg).
    params : dict
        The sensor's schedule parameters (:func:`mode_camera`).
    exposure_ms : float
        The exposure 2T, ms: the shutter is open over [0, exposure_ms], and the paper's time is
        t = shutter time - T.

    Returns
    -------
    dict
        A ``mi.load_dict`` entry with an RGB float32 ``hdrfilm`` of width x height px, a box
        reconstruction filter (samples stay in their pixel, as the analytic PSFs assume) and an
        ``independent`` sampler of ``spec.spp`` samples per pixel. For ``reference`` it is a
        ``perspective`` (pinhole) sensor; otherwise
        :func:`~pacam_render.render.registry.sensor_dict` with pixel values scaled to the
        :data:`REFERENCE_EXPOSURE_MS` exposure.

    Raises
    ------
    ParameterError
        If :func:`~pacam_render.render.registry.sensor_dict` rejects the parameters.

    Notes
    -----
    Except for the reference, this activates a Mitsuba variant if none is active and registers
    the sensor plugins.
    """
    from ..render.registry import sensor_dict

    film = {
        "type": "hdrfilm",
        "width": spec.width,
        "height": spec.height,
        "rfilter": {"type": "box"},  # samples stay in their pixel, as the analytic PSFs assume
        "pixel_format": "rgb",
        "component_format": "float32",
    }
    if spec.crop is not None:
        x, y, w, h = spec.crop
        film.update(crop_offset_x=x, crop_offset_y=y, crop_width=w, crop_height=h)
    sampler = {"type": "independent", "sample_count": spec.spp}
    if spec.mode == "reference":
        return {"type": "perspective", "fov": design.fov_deg, "film": film, "sampler": sampler}
    return sensor_dict(
        fov=design.fov_deg,
        shutter_open=0.0,
        shutter_close=exposure_ms,
        reference_exposure=REFERENCE_EXPOSURE_MS,
        film=film,
        sampler=sampler,
        **params,
    )


@dataclass(frozen=True)
class Step:
    """One render of a moving scene: shutter window [t0, t1] ms, geometry at t_mid_ms."""

    pattern: int
    t0: float
    t1: float
    spp: int

    @property
    def t_mid_paper_ms(self) -> float:
        """Mid-time of the window, ms, on the shutter's clock (t0, t1): subtract T for the paper's
        t in [-T, T]."""
        return 0.5 * (self.t0 + self.t1)


def plan_steps(
    edges: np.ndarray,
    is_open: np.ndarray,
    speed_px_per_ms: float,
    spec,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> list[Step]:
    """Time steps within each open pattern window, and their share of the spp budget.

    Parameters
    ----------
    edges : ndarray
        The n + 1 pattern boundaries on the shutter's clock, ms.
    is_open : ndarray of bool
        Whether each of the n pattern windows lets light in; closed windows get no steps.
    speed_px_per_ms : float
        The fastest image speed of any moving shape, px/ms.
    spec : CaptureSpec
        Uses ``max_step_px`` (px) and ``spp``.
    max_steps : int, optional
        The most steps allowed (``--max-steps``).

    Returns
    -------
    list of Step
        In time order: each open window [a, b] is cut into
        m = max(1, ceil(v_max (b - a) / max_step_px)) equal steps, so that nothing moves more
        than ``max_step_px`` between steps.

    Raises
    ------
    ParameterError
        If the plan needs more than ``max_steps`` steps (counted before any is built).

    Notes
    -----
    The spp budget is shared in proportion to duration: a step of duration d gets
    floor(spp d / D) samples (D the open time), at least 1, and the samples still to give go to
    the largest remainders. The total is ``spec.spp``, or more where the minimum of 1 per step
    forces it.
    """
    windows = [(k, a, b) for k, (a, b, o) in enumerate(zip(edges[:-1], edges[1:], is_open)) if o]
    counts = [speed_px_per_ms * (b - a) / spec.max_step_px - 1e-9 for _, a, b in windows]
    check_count(
        "time steps of this capture (fastest image speed "
        f"{speed_px_per_ms:.4g} px/ms, --max-step-px {spec.max_step_px:g})",
        sum(_n_steps(c) for c in counts),
        max_steps,
        "--max-steps",
        "; or raise --max-step-px",
    )
    pieces = []
    for (k, a, b), c in zip(windows, counts):
        e = np.linspace(a, b, _n_steps(c) + 1)
        pieces += [(k, float(x), float(y)) for x, y in zip(e[:-1], e[1:])]
    dur = np.array([y - x for _, x, y in pieces])
    share = spec.spp * dur / dur.sum()
    spp = np.maximum(1, np.floor(share)).astype(int)
    left = spec.spp - spp.sum()
    if left > 0:  # largest remainders get the samples still to give
        spp[np.argsort(-(share - np.floor(share)), kind="stable")[:left]] += 1
    return [Step(k, x, y, int(n)) for (k, x, y), n in zip(pieces, spp)]


def _n_steps(count: float) -> float:
    """Steps for a window that the fastest point crosses in ``count`` step lengths."""
    return max(1, math.ceil(count)) if math.isfinite(count) else math.inf


def _step_seed(seed: int, index: int) -> int:
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0] >> 1)


@dataclass
class Capture:
    """A finished capture: the image, optional per-pattern images, extra layers (the sensor's
    ``raw`` and ``noisy``), and its :class:`~pacam_render.exposure.record.CaptureRecord`."""

    image: np.ndarray
    patterns: dict[int, np.ndarray]
    record: CaptureRecord
    extra_layers: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def meta(self) -> dict:
        """The record as the JSON sidecar holds it (a fresh dict: change ``record``)."""
        return self.record.to_json()


def render_capture(
    spec: CaptureSpec,
    partial_dir: Path | None = None,
    progress: bool = True,
    save_every_s: float = 5.0,
    stop_after_steps: int | None = None,
    description=None,
    max_steps: int = DEFAULT_MAX_STEPS,
    max_samples: int = DEFAULT_MAX_SAMPLES,
    truth: bool = True,
) -> Capture:
    """Render one capture, and its ground-truth layers.

    A static scene, or the reference, is one render; a moving scene is integrated over the
    time steps of :func:`plan_steps` (see the module docstring).

    Parameters
    ----------
    spec : CaptureSpec
        What to capture.
    partial_dir : pathlib.Path, optional
        Folder for the finished steps of a moving scene
        (:class:`~pacam_render.exposure.checkpoint.Checkpoint`): the same capture resumes from
        them, and the folder is removed when the capture finishes. Its parent is locked
        (:func:`~pacam_render.io.lock.output_lock`) while the capture runs. None keeps nothing.
    progress : bool, optional
        Show a progress bar over the steps.
    save_every_s : float, optional
        Seconds between saves of the finished steps to ``partial_dir``, s.
    stop_after_steps : int, optional
        Stop after this many steps: they are saved and :class:`CaptureInterrupted` is raised.
    description : SceneDescription, optional
        A scene to capture instead of ``spec.scene``.
    max_steps : int, optional
        The most time steps a moving capture may take (``--max-steps``).
    max_samples : int, optional
        The most camera samples, spp x width x height (``--max-samples``).
    truth : bool, optional
        Also render the ground-truth layers ``sharp``, ``depth``, ``object_id`` and
        ``velocity`` (:mod:`pacam_render.exposure.truth`; ``--no-truth`` leaves them out).

    Returns
    -------
    Capture
        The image, (height, width, 3) float64 in radiance x (open area / full aperture) x
        (exposure / 45 ms); the per-pattern images of a moving scene when ``spec.per_pattern``
        is set; the ground-truth layers in ``extra_layers``, with their legend in
        ``record.objects``; and the :class:`~pacam_render.exposure.record.CaptureRecord`.

    Raises
    ------
    ParameterError
        If the preset, mode or scene is unknown, the camera cannot be built, the work exceeds
        ``max_steps``, ``max_samples`` or the memory available, or ``partial_dir`` is in use.
    CaptureInterrupted
        When ``stop_after_steps`` steps are done, or on SIGINT or SIGTERM during the steps; the
        finished steps are saved first.

    Warns
    -----
    PacamWarning
        When the steps take more samples than ``spec.spp``, a checkpoint is not resumed, or an
        option does not apply to the mode; each note is also kept in ``record.notes``.

    Notes
    -----
    Selects and activates a Mitsuba variant. The fastest image speed is taken over the paper's
    t in [-T, T] (the exposure is 2T), and each step renders the geometry at its mid-time.
    Same-seed captures are bit-identical (:mod:`pacam_render.render.passes`).
    """
    check_budget(spec, max_samples, truth)
    lock = _partial_lock(partial_dir)
    with lock, warnings.catch_warnings(record=True) as caught, deferred_signals() as flag:
        warnings.simplefilter("always", PacamWarning)
        run = _Run(partial_dir, progress, save_every_s, stop_after_steps, max_steps, flag)
        cap = _render(spec, description, run, truth)
    cap.record.notes = _replay(caught)
    return cap


def _partial_lock(partial_dir):
    """The lock of the folder that holds ``partial_dir`` (none without one)."""
    if partial_dir is None:
        return contextlib.nullcontext()
    from ..io.lock import output_lock

    return output_lock(Path(partial_dir).parent)


def _replay(caught) -> list[str]:
    """Show caught warnings to the caller as they would have been; return the notes among them."""
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return [str(w.message) for w in caught if issubclass(w.category, PacamWarning)]


def check_budget(
    spec: CaptureSpec, max_samples: int = DEFAULT_MAX_SAMPLES, truth: bool = False
) -> None:
    """Refuse a capture whose samples or memory are beyond bounds, before any work.

    Raises
    ------
    ParameterError
        Naming ``--max-samples``, or ``--width`` and ``--height`` for memory (about 160 bytes
        per pixel, plus 24 per pixel and pattern with ``per_pattern`` and 96 with ``truth``).
    """
    from ..render.passes import MAX_WAVEFRONT

    w, h = spec.image_size
    pixels = w * h
    per_px = 160 + (24 * paper.N_PATTERNS if spec.per_pattern else 0) + (96 if truth else 0)
    check_memory(f"a {w}x{h} capture", per_px * pixels, "--width/--height or --crop")
    if pixels > MAX_WAVEFRONT:
        raise ParameterError(
            f"a {w}x{h} image has more than Mitsuba's {MAX_WAVEFRONT} samples per pass at 1 "
            "spp; reduce --width/--height or --crop"
        )
    check_count(
        f"samples of this capture (--spp {spec.spp} x {w} x {h} px)",
        spec.spp * pixels,
        max_samples,
        "--max-samples",
    )


def _render(spec: CaptureSpec, description, run: _Run, truth: bool) -> Capture:
    from ..render.backend import select_variant
    from ..render.passes import render_passes
    from ..scenes import load_scene

    variant = select_variant()
    _note_ignored_options(spec)
    design = capture_design(spec)
    cam, params = mode_camera(design, spec.mode)
    _note_binning(spec, cam)
    desc = description if description is not None else load_scene(spec.scene)
    t_start = time.perf_counter()
    scene = desc.load(sensor=sensor_entry(spec, cam, params, cam.exposure_ms))
    sensor = scene.sensors()[0]
    run.check_signal()
    layers, objects = _truth(scene, desc, spec, design, run) if truth else ({}, None)
    if desc.is_static or spec.mode == "reference":  # one pass, no geometry update
        if spec.per_pattern:
            _note("--per-pattern keeps nothing here: a static scene or the reference is one pass")
        image = render_passes(scene, spec.spp, spec.seed, run.signalled)
        run.check_signal()  # a partial image (None) never leaves
        patterns, steps = {}, {"n_steps": 1, "n_geometry_updates": 0, "effective_spp": spec.spp}
    else:
        image, patterns, steps = _render_moving(scene, sensor, desc, design, cam, spec, run)
    if spec.mode == "reference" and truth:
        layers["sharp"] = image
    seconds = time.perf_counter() - t_start
    record = _record(spec, design, cam, params, sensor, variant, seconds, steps)
    record.objects = objects
    return Capture(image, patterns, record, {k: layers[k] for k in TRUTH_LAYERS if k in layers})


def _truth(scene, desc, spec, design, run: _Run) -> tuple[dict, dict]:
    """The ground-truth layers, rendered before the steps move anything (scene at t = 0).

    The reference's own image is its ``sharp`` layer, so it is not rendered twice."""
    from .truth import render_truth

    layers, objects = render_truth(
        scene, desc, spec, design, spec.mode != "reference", run.signalled
    )
    if layers is None:
        run.check_signal()
    return layers, objects


def _note(message: str) -> None:
    warnings.warn(message, PacamWarning, stacklevel=3)


def _note_ignored_options(spec: CaptureSpec) -> None:
    """Options the mode does not use: say so rather than drop them silently."""
    if spec.cover_px_per_ms is not None and mode(spec.mode).refocus:
        _note(
            f"--cover has no effect in {spec.mode} mode: it focuses on the object, so the "
            "solved defocus is not used (it applies to coded, coded_continuous and levin)"
        )


def _note_binning(spec: CaptureSpec, cam: CameraDesign) -> None:
    """A coded capture whose blur is sub-pixel is a binned camera: say so, and what to do."""
    full = preset(spec.preset)
    if not mode(spec.mode).needs_parallax or cam.r_px >= 1.0:
        return
    binned = full.width_px / spec.width
    _note(
        f"at {spec.width}x{spec.height} px the sensor is the preset's {full.width_px}x"
        f"{full.height_px} binned {binned:.3g}x: the coded blur is sub-pixel (r = "
        f"{cam.r_px:.3g} px, a_i = {cam.a_i_px_per_ms2:.3g} px/ms^2, invariant |s| <= "
        f"{cam.velocity_range_px_per_ms:.3g} px/ms at this size); to see the camera at its real "
        f"pixel scale, render a window of the full sensor with --crop X,Y,W,H"
    )


def _render_moving(scene, sensor, desc, design, cam, spec, run: _Run):
    """Integrate a moving scene over the time steps of :func:`plan_steps`."""
    from ..scenes import fastest_image_speed_px_per_ms
    from .checkpoint import Checkpoint, resume_parts

    exposure = cam.exposure_ms
    speed = fastest_image_speed_px_per_ms(desc, design, (-0.5 * exposure, 0.5 * exposure))
    plan = sensor.plan
    steps = plan_steps(plan.pattern_edges, plan.is_open, speed, spec, run.max_steps)
    effective = sum(s.spp for s in steps)
    if effective > spec.spp:
        _note(
            f"{len(steps)} time steps need at least 1 sample each: the capture takes "
            f"{effective} spp instead of --spp {spec.spp}; raise --max-step-px for fewer steps"
        )
    parts = resume_parts(spec, scene, desc, steps, _versions(), _variant())
    store = Checkpoint(None if run.partial_dir is None else Path(run.partial_dir), parts)
    image, patterns, meta = _integrate(scene, sensor, desc, steps, spec, exposure, run, store)
    return image, patterns, {**meta, "fastest_image_speed_px_per_ms": speed}


class CaptureInterrupted(RuntimeError):
    """The capture stopped early (``stop_after_steps``, SIGINT or SIGTERM); the finished steps
    are on disk when a ``partial_dir`` was given."""

    def __init__(self, message: str, done: int = 0, total: int = 0, signum: int | None = None):
        super().__init__(message)
        self.done, self.total, self.signum = done, total, signum


@dataclass(frozen=True)
class _Run:
    """How to run the steps: where to keep finished ones, progress, deliberate interruption,
    and the flag that SIGINT and SIGTERM set (:func:`~.checkpoint.deferred_signals`)."""

    partial_dir: Path | None
    progress: bool
    save_every_s: float
    stop_after_steps: int | None
    max_steps: int = DEFAULT_MAX_STEPS
    flag: dict = field(default_factory=lambda: {"signal": None})

    def signalled(self) -> bool:
        return self.flag["signal"] is not None

    def check_signal(self) -> None:
        """Stop a capture that has no finished steps to save."""
        if self.signalled():
            raise _interrupted(0, 0, self.flag["signal"], None)


def _integrate(scene, sensor, desc, steps, spec, exposure, run: _Run, store):
    from tqdm import tqdm

    from ..render.passes import render_passes

    anim = desc.animator(scene)
    shape = (spec.image_size[1], spec.image_size[0], 3)
    resumed = store.load(shape)
    done, acc, pats = resumed if resumed else (0, np.zeros(shape), {})
    mid = 0.5 * exposure  # paper time t = shutter time - mid
    last_save = time.perf_counter()
    bar = tqdm(total=len(steps), initial=done, disable=not run.progress, unit="step",
               desc=f"{spec.mode} {spec.scene}", leave=False)  # fmt: skip
    with bar:
        for i in range(done, len(steps)):
            st = steps[i]
            anim.set_time(st.t_mid_paper_ms - mid)
            sensor.configure(time_window=(st.t0, st.t1))
            img = render_passes(scene, st.spp, _step_seed(spec.seed, i), run.signalled)
            if img is None:  # a signal came during the step: keep only the steps before it
                if i == 0:
                    run.check_signal()
                store.save(i, acc, pats)
                raise _interrupted(i, len(steps), run.flag["signal"], run.partial_dir)
            acc += img
            if spec.per_pattern:
                pats[st.pattern] = pats.get(st.pattern, 0.0) + img
            bar.update(1)
            finished = i + 1
            stop = run.stop_after_steps is not None and finished >= run.stop_after_steps
            if (stop or run.signalled()) and finished < len(steps):
                store.save(finished, acc, pats)
                raise _interrupted(finished, len(steps), run.flag["signal"], run.partial_dir)
            if time.perf_counter() - last_save > run.save_every_s and finished < len(steps):
                store.save(finished, acc, pats)
                last_save = time.perf_counter()
    sensor.configure(time_window=None)
    store.clear()
    meta = {
        "n_steps": len(steps),
        "n_geometry_updates": anim.n_updates,
        "resumed_from_step": done,
        "effective_spp": int(sum(s.spp for s in steps)),
    }
    return acc, pats, meta


def _interrupted(done: int, total: int, signum, partial_dir) -> CaptureInterrupted:
    why = "stopped" if signum is None else f"interrupted ({signal.Signals(signum).name})"
    if total == 0:
        return CaptureInterrupted(f"{why} before any time step finished; nothing to resume")
    where = (
        f"; they are saved in {partial_dir}: run the same command again to resume"
        if partial_dir is not None
        else "; nothing was saved (no partial_dir)"
    )
    return CaptureInterrupted(f"{why} after {done} of {total} steps{where}", done, total, signum)


def _versions() -> dict:
    import drjit
    import mitsuba

    from .. import __version__

    return {
        "pacam_render": __version__,
        "mitsuba": mitsuba.__version__,
        "drjit": drjit.__version__,
        "numpy": np.__version__,
    }


def _variant() -> str:
    import mitsuba

    return mitsuba.variant()


def _record(spec, design, cam, params, sensor, variant, seconds, steps: dict) -> CaptureRecord:
    """The capture's record: the one place that builds it."""
    weight = 1.0 if spec.mode == "reference" else float(sensor.plan.mean_weight())
    crop = None
    if spec.crop is not None:
        x, y, w, h = spec.crop
        crop = {"x": x, "y": y, "width": w, "height": h}
        crop.update(sensor_width_px=spec.width, sensor_height_px=spec.height)
    return CaptureRecord(
        crop=crop,
        spec=asdict(spec),
        mode=spec.mode,
        camera=cam.inputs(),
        optics=cam.summary(),
        coded_design=design.summary(),
        sensor_params={k: v for k, v in params.items() if not hasattr(v, "shape")},
        exposure_ms=cam.exposure_ms,
        reference_exposure_ms=REFERENCE_EXPOSURE_MS,
        light_factor=weight,
        render_seconds=seconds,
        variant=variant,
        versions=_versions(),
        **steps,
    )


def write_capture(cap: Capture, out: Path, force: bool) -> list[Path]:
    """capture.exr (float32 layers), capture.png (sRGB preview), capture.json.

    Parameters
    ----------
    cap : Capture
        The capture to write.
    out : pathlib.Path
        The output folder (created if missing).
    force : bool
        Overwrite existing files.

    Returns
    -------
    list of pathlib.Path
        The three files, in that order.

    Raises
    ------
    ParameterError
        If a file already exists and ``force`` is false.

    Notes
    -----
    capture.exr holds the layers ``capture`` (the image), the extra layers (the ground truth
    of :mod:`~pacam_render.exposure.truth`, and ``raw`` and ``noisy`` after the sensor) and
    ``subNN`` per pattern image. The preview shows the
    ``noisy`` layer when there is one (else the image), exposed by 1 / ``light_factor``
    (auto-exposed when that is 0); capture.json is the record. Each file is
    written to a temporary file and renamed.
    """
    from ..io.exr import write_exr
    from ..io.preview import srgb8, write_png

    layers = {"capture": cap.image, **cap.extra_layers}
    for k, img in sorted(cap.patterns.items()):
        layers[f"sub{k:02d}"] = img
    lf = cap.record.light_factor
    exposure = 1.0 / lf if lf > 0 else None
    shown = cap.extra_layers.get("noisy", cap.image)  # what the camera delivers, with --sensor
    return [
        write_exr(out / "capture.exr", layers, force=force),
        write_png(out / "capture.png", srgb8(shown, exposure), force=force),
        write_json(out / "capture.json", cap.record.to_json(), force=force),
    ]
