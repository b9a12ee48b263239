"""Captures: a scene rendered through the programmable-aperture camera over a whole exposure.

Exposure integration (:mod:`.integrate`). A capture is the mean of independent passes. A static
scene is one render per pass: each ray's time selects the pattern in the sensor, so there is no
loop and no geometry update. A moving scene is split at the pattern boundaries, and each pattern
window into time steps of at most ``max_step_px`` (default 0.5 px) of image motion; each pass
poses the geometry at a random time within each step, so the steps add noise, not bias. The
passes' spread is the capture's Monte Carlo error (:mod:`.estimate`), recorded in
``render_error``; a capture can also be rendered until that error meets a target. Every step of
every pass has its own seed, so an interrupted capture resumes from the work on disk and gives
the same image as an uninterrupted run.

Units. Pixel values are Mitsuba radiance x (open area / full aperture) x (exposure / 45 ms):
a white diffuse surface seen through the full F2.8 aperture for 45 ms reads about its
reflectance. So a capture is proportional to the light it collects, and captures of different
modes compare directly (``light_factor`` in the JSON is that scale for each mode).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import time
import warnings
from dataclasses import asdict, dataclass, field, replace
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
from ..model.modes import DESIGNED_REFUSED, capture_camera, mode, sensor_params
from ..model.modes import MODES as MODE_TABLE
from ..render.registry import sensor_entry
from ..render.samplers import DEFAULT_SAMPLER, check_sampler, quantum
from .checkpoint import deferred_signals
from .estimate import check_passes
from .integrate import CaptureInterrupted, Run
from .record import CaptureRecord, layer_unit
from .truth import TRUTH_LAYERS, render_truth

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

    ``spp`` is shared among ``passes`` independent passes (at least 2: their spread measures the
    Monte Carlo error); ``sampler`` is Mitsuba's sample generator (:mod:`~..render.samplers`).
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
    passes: int = 2
    sampler: str = DEFAULT_SAMPLER

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
        check_passes(self.passes)
        check_sampler(self.sampler)
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
            The first 16 hex digits of the SHA-256 of the spec's fields as sorted JSON, and of
            the contents of the schedule file it names (a file rewritten in place is another
            capture).
        """
        h = hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode())
        if self.schedule is not None and Path(self.schedule).is_file():
            h.update(Path(self.schedule).read_bytes())
        return h.hexdigest()[:16]


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
    unused = _schedule_unused(mode) if design.designed else []
    if "openings" in unused:  # the mode shows none of them: its camera leaves them out
        text = f"{design.name}, its {_words(unused)} not used"
        design = design.with_(pattern_centres_mm=None, name=text)
    cam = capture_camera(design, mode)
    return cam, sensor_params(cam, mode)


def _schedule_unused(name: str) -> list[str]:
    """The parts of a designed schedule that a ``name`` capture does not use."""
    m = mode(name)
    if name in DESIGNED_REFUSED:  # refused where the design is made
        return []
    if m.schedule is None:  # the pinhole reference
        return ["openings", "focus", "radius", "exposure"]
    unused = [] if m.needs_parallax else ["openings"]
    unused += ["focus"] if m.refocus else []
    unused += ["radius"] if m.full_opening else []
    return unused + (["exposure"] if m.exposure_ms is not None else [])


def _words(items: list[str]) -> str:
    """``a, b and c``."""
    return " and ".join(items) if len(items) < 3 else f"{', '.join(items[:-1])} and {items[-1]}"


@dataclass
class Capture:
    """A finished capture: the image, optional per-pattern images, extra layers (the sensor's
    ``raw`` and ``noisy``), and its :class:`~pacam_render.exposure.record.CaptureRecord`."""

    image: np.ndarray
    patterns: dict[int, np.ndarray]
    record: CaptureRecord
    extra_layers: dict[str, np.ndarray] = field(default_factory=dict)
    mc_sigma: np.ndarray | None = None
    """Per-pixel Monte Carlo sigma of ``image``, its units (``record.render_error`` sums it up)."""

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
    target=None,
    pilot_only: bool = False,
    keep_partial: bool = False,
) -> Capture:
    """Render one capture, its Monte Carlo error, and its ground-truth layers.

    A capture is ``spec.passes`` independent passes of ``spec.spp / passes`` samples, or, with
    a ``target``, as many as its Monte Carlo sigma needs; a static scene, or the reference, is
    one render per pass, a moving scene the time steps of
    :func:`~pacam_render.exposure.integrate.plan_steps` (see :mod:`.integrate`).

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
        ``sharp`` is rendered in passes like the capture, to the capture's target in white
        units when it has one.
    target : NoiseTarget, optional
        Render until the Monte Carlo sigma (RMS over the window, the capture's units) meets
        it (:class:`~pacam_render.exposure.estimate.AbsoluteTarget`, or
        :class:`~pacam_render.sensor.apply.SensorTarget` for a multiple of the sensor's noise);
        ``spec.spp`` is then not used, and ``max_samples`` bounds the work.
    pilot_only : bool, optional
        With a ``target``: stop after the pilot passes, keep them in ``partial_dir`` for the
        capture to resume from, and return the pilot's image and error; its
        ``render_error["planned_spp"]`` predicts the samples the target needs, and
        ``render_error["predicted_seconds"]`` the time the rest takes (one step of a main pass
        timed). No ground truth.
    keep_partial : bool, optional
        Keep the finished passes in ``partial_dir`` when the capture is done, for the caller
        to remove once the capture is safely written (a failed write then loses no rendering:
        the same capture resumes from them at once).

    Returns
    -------
    Capture
        The image, (height, width, 3) float64 in radiance x (open area / full aperture) x
        (exposure / 45 ms); its per-pixel Monte Carlo sigma (``mc_sigma``); the per-pattern
        images of a moving scene when ``spec.per_pattern`` is set; the ground-truth layers in
        ``extra_layers``, with their legend in ``record.objects``; and the
        :class:`~pacam_render.exposure.record.CaptureRecord`, whose ``render_error`` states
        the error and its cost.

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
        When the steps take more samples than ``spec.spp``, a target is not met within
        ``max_samples``, a checkpoint is not resumed, or an option does not apply to the mode;
        each note is also kept in ``record.notes``.

    Notes
    -----
    Selects and activates a Mitsuba variant. The fastest image speed is taken over the paper's
    t in [-T, T] (the exposure is 2T), and each step renders the geometry at a random time in
    it. Same-seed captures are bit-identical (:mod:`pacam_render.render.passes`).
    """
    check_budget(spec, max_samples, truth, target is not None)
    lock = _partial_lock(partial_dir)
    with lock, warnings.catch_warnings(record=True) as caught, deferred_signals() as flag:
        warnings.simplefilter("always", PacamWarning)
        run = Run(partial_dir, progress, save_every_s, stop_after_steps, max_steps, flag)
        run = replace(run, max_samples=max_samples, pilot_only=pilot_only and target is not None)
        cap = _render(spec, description, run, truth, target, keep_partial)
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
    spec: CaptureSpec,
    max_samples: int = DEFAULT_MAX_SAMPLES,
    truth: bool = False,
    targeted: bool = False,
) -> None:
    """Refuse a capture whose samples or memory are beyond bounds, before any work.

    A capture rendered to a noise target (``targeted``) has no spp to check: it stops at
    ``max_samples`` instead.

    Raises
    ------
    ParameterError
        Naming ``--max-samples``, or ``--width`` and ``--height`` for memory (about 210 bytes
        per pixel, plus 24 per pixel and pattern with ``per_pattern`` and 96 with ``truth``).
    """
    from ..render.passes import MAX_WAVEFRONT

    w, h = spec.image_size
    pixels = w * h
    per_px = 208 + (24 * paper.N_PATTERNS if spec.per_pattern else 0) + (96 if truth else 0)
    check_memory(f"a {w}x{h} capture", per_px * pixels, "--width/--height or --crop")
    if pixels > MAX_WAVEFRONT:
        raise ParameterError(
            f"a {w}x{h} image has more than Mitsuba's {MAX_WAVEFRONT} samples per pass at 1 "
            "spp; reduce --width/--height or --crop"
        )
    if not targeted:
        check_count(
            f"samples of this capture (spp {spec.spp} x {w} x {h} px)",
            spec.spp * pixels,
            max_samples,
            "max_samples",
        )


def _render(spec: CaptureSpec, description, run: Run, truth: bool, target, keep: bool) -> Capture:
    from ..render.backend import select_variant
    from ..scenes import load_scene
    from ..scenes.units import check_units
    from .checkpoint import Checkpoint, resume_parts
    from .integrate import integrate

    variant = select_variant()
    _note_ignored_options(spec)
    design = capture_design(spec)
    cam, params = mode_camera(design, spec.mode)
    _note_binning(spec, cam)
    desc = description if description is not None else load_scene(spec.scene)
    t_start = time.perf_counter()
    scene = desc.load(sensor=sensor_entry(spec, cam, params, cam.exposure_ms))
    sensor = scene.sensors()[0]
    check_units(scene, design)  # a scene in metres renders near-black with no other word
    run.check_signal()
    exp, speed = _exposure(scene, sensor, desc, design, cam, spec, run)
    record = _record(spec, design, cam, params, sensor, variant, 0.0, {})
    plan = {"windows": exp.windows, "target": None if target is None else target.to_json()}
    parts = resume_parts(spec, scene, desc, plan, _versions(), variant)
    store = Checkpoint(None if run.partial_dir is None else Path(run.partial_dir), parts)
    prog = integrate(exp, spec, run, store, target, record, f"{spec.mode} {spec.scene}")
    render_s = time.perf_counter() - t_start
    if not run.pilot_only:  # a pilot stops short of its target by design
        _note_samples(spec, exp, prog, target)
    if exp.moving:  # back to t = 0 for the ground truth
        sensor.configure(time_window=None)
        exp.animator.set_time(0.0)
    image = prog.stats.mean()
    if run.pilot_only or keep or truth:  # what is done stays on disk until it is not needed
        store.save(prog.state(), prog.arrays())
    truth = truth and not run.pilot_only
    layers, objects, sharp = _truth(scene, desc, spec, design, run, prog, record, store, truth)
    if spec.mode == "reference" and truth:
        layers["sharp"], sharp = image, prog.stats
    steps = {
        "n_steps": exp.steps_per_pass(prog.sched.groups[-1][0]),
        "n_geometry_updates": exp.animator.n_updates if exp.moving else 0,
        "effective_spp": prog.stats.spp,
        "resumed_from_step": prog.resumed_from if exp.moving else None,
        "fastest_image_speed_px_per_ms": speed if exp.moving else None,
    }
    record = _record(
        spec, design, cam, params, sensor, variant, time.perf_counter() - t_start, steps
    )
    record.objects = objects
    record.design_fit = _design_fit(layers, objects, cam, spec.mode)
    ids = layers.get("object_id")
    record.render_error = _render_error(prog, exp, spec, render_s, objects, ids, record, sharp)
    if not run.pilot_only and not keep:
        store.clear()
    patterns = prog.stats.pattern_means() if spec.per_pattern else {}
    layers = {k: layers[k] for k in TRUTH_LAYERS if k in layers}
    return Capture(image, patterns, record, layers, prog.stats.sigma_px())


def _exposure(scene, sensor, desc, design, cam, spec, run: Run):
    """The :class:`~.integrate.Exposure` of a capture, and the fastest image speed (px/ms)."""
    from ..scenes import fastest_image_speed_px_per_ms
    from .steps import Exposure, plan_windows

    w, h = spec.image_size
    exp = Exposure(scene, sensor, quantum=quantum(spec.sampler), pixels=w * h)
    if desc.is_static or spec.mode == "reference":  # one render per pass, no geometry update
        if spec.per_pattern:
            _note("--per-pattern keeps nothing here: a static scene or the reference is one pass")
        return exp, 0.0
    exposure = cam.exposure_ms
    speed = fastest_image_speed_px_per_ms(desc, design, (-0.5 * exposure, 0.5 * exposure))
    plan = sensor.plan
    exp.windows = plan_windows(
        plan.pattern_edges, plan.is_open, speed, spec.max_step_px, run.max_steps
    )
    exp.animator, exp.mid_ms = desc.animator(scene), 0.5 * exposure
    return exp, speed


def _note_samples(spec: CaptureSpec, exp, prog, target) -> None:
    """Say when the passes took more samples than asked, or a target was not met."""
    sched = prog.sched
    if target is None and prog.stats.spp > spec.spp:
        per = "time step" if exp.moving else "pass"
        _note(
            f"{spec.passes} passes of at least {exp.quantum} spp per {per} ({spec.sampler}) take "
            f"{prog.stats.spp} spp where {spec.spp} were asked"
            + ("; each pattern needs one step" if exp.moving else "")
        )
    if target is not None and not sched.met:
        from .estimate import rms

        _note(
            f"the noise target was not met: Monte Carlo sigma {rms(prog.stats.variance()):.3g} > "
            f"{sched.target_sigma:.3g} after {prog.stats.spp} spp, the most that max_samples "
            "allows; raise max_samples, or render a smaller crop"
        )


def _truth(scene, desc, spec, design, run: Run, prog, record, store, truth: bool):
    """The ground-truth layers (the scene back at t = 0), and the sharp layer's passes.

    The sharp layer is rendered in passes like the capture: to the capture's target in white
    units when it had one. The reference's own image is its ``sharp`` layer, so it is not
    rendered twice. The capture's passes are saved first, so that an interrupt here loses none.
    """
    if not truth:
        return {}, None, None
    goal = prog.sched.target_sigma
    goal = None if goal is None else goal / max(record.light_factor, 1e-300)
    quiet = replace(run, progress=False, stop_after_steps=None, partial_dir=None)
    try:
        return render_truth(scene, desc, spec, design, spec.mode != "reference", quiet, goal)
    except CaptureInterrupted as exc:
        where = run.partial_dir if store.folder is not None else None
        raise CaptureInterrupted(
            "interrupted while rendering the ground truth; the capture's steps are "
            + (f"saved in {where}: run the same command again to resume" if where else "lost"),
            exc.done,
            exc.total,
            exc.signum,
        ) from None


def _design_fit(layers: dict, objects: dict | None, cam, mode: str) -> dict | None:
    """Each object against the design's depth and speed range (:mod:`.design_fit`), noted."""
    from .design_fit import fit_notes, object_fit

    if mode == "reference" or not objects or "depth" not in layers:
        return None
    fit = object_fit(layers, objects, cam, mode)
    for line in fit_notes(fit, cam, mode):
        _note(line)
    return fit


def _render_error(prog, exp, spec, seconds, objects, ids, record, sharp) -> dict:
    """``render_error`` of the record: the Monte Carlo sigma (capture units), its cost, and the
    time steps' error (none: stratified random times make them noise, counted in the sigma)."""
    from .estimate import error_summary, rms

    out = error_summary(prog.stats, objects, ids)
    lf = record.light_factor
    out["mc_sigma_white_units"] = out["mc_sigma"] / lf if lf > 0 else None
    out.update(sampler=spec.sampler, seconds=round(seconds, 3))
    out["time_steps_per_pass"] = exp.steps_per_pass(prog.sched.groups[-1][0]) if exp.moving else 0
    out["time_step_bias"] = 0.0
    out["time_sampling"] = (
        "stratified random times, one per step and pass: unbiased, their noise is in mc_sigma"
        if exp.moving
        else "none: every ray samples the whole exposure"
    )
    sched = prog.sched
    if sched.target_sigma is not None:
        out["target_sigma"], out["target_met"] = sched.target_sigma, bool(sched.met)
        out["planned_spp"] = sched.planned_spp
    if prog.predicted_s:
        out["predicted_seconds"] = round(prog.predicted_s, 3)
    if sharp is not None:
        out["sharp_mc_sigma"] = rms(sharp.variance())
    return out


def _note(message: str) -> None:
    warnings.warn(message, PacamWarning, stacklevel=3)


def _note_ignored_options(spec: CaptureSpec) -> None:
    """Options the mode does not use: say so rather than drop them silently."""
    if spec.cover_px_per_ms is not None and mode(spec.mode).refocus:
        _note(
            f"--cover has no effect in {spec.mode} mode: it focuses on the object, so the "
            "solved defocus is not used (it applies to coded, coded_continuous and levin)"
        )
    unused = _schedule_unused(spec.mode) if spec.schedule is not None else []
    if unused:  # recorded in the capture's notes; its camera leaves the openings out
        used = {"radius", "exposure"} - set(unused)
        _note(
            f"--schedule's {_words(unused)} are not used in {spec.mode} mode ("
            f"{MODE_TABLE[spec.mode].summary}): "
            + (f"only its {_words(sorted(used))} are" if used else "it has no effect")
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


def write_capture(cap: Capture, out: Path, force: bool, error_layer: bool = False) -> list[Path]:
    """capture.exr (float32 layers), capture.png (sRGB preview), capture.json.

    Parameters
    ----------
    cap : Capture
        The capture to write.
    out : pathlib.Path
        The output folder (created if missing).
    force : bool
        Overwrite existing files.
    error_layer : bool, optional
        Also write the per-pixel Monte Carlo sigma (``cap.mc_sigma``) as the ``mc_sigma`` layer.

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
    (auto-exposed when that is 0); capture.json is the record, with each layer's unit
    (``units``; :func:`~pacam_render.exposure.record.read_capture` reads them on one scale).
    Each file is written to a temporary file and renamed.
    """
    from ..io.exr import write_exr
    from ..io.preview import srgb8, write_png

    layers = {"capture": cap.image, **cap.extra_layers}
    if error_layer and cap.mc_sigma is not None:
        layers["mc_sigma"] = cap.mc_sigma
    for k, img in sorted(cap.patterns.items()):
        layers[f"sub{k:02d}"] = img
    cap.record.units = {name: layer_unit(name) for name in layers}
    lf = cap.record.light_factor
    exposure = 1.0 / lf if lf > 0 else None
    shown = cap.extra_layers.get("noisy", cap.image)  # what the camera delivers, with --sensor
    return [
        write_exr(out / "capture.exr", layers, force=force),
        write_png(out / "capture.png", srgb8(shown, exposure), force=force),
        write_json(out / "capture.json", cap.record.to_json(), force=force),
    ]
