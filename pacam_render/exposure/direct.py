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

import time
import warnings
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path

from ..capture.record import layer_unit
from ..capture.result import Capture
from ..errors import ParameterError
from ..io.exr import write_exr
from ..io.outputs import write_json
from ..io.preview import srgb8, write_png
from ..io.signals import deferred_signals
from ..limits import (
    DEFAULT_MAX_SAMPLES,
    DEFAULT_MAX_STEPS,
    PacamWarning,
    check_count,
    check_memory,
    note,
)
from ..model import paper
from ..render.passes import MAX_WAVEFRONT
from ..render.registry import sensor_entry
from ..render.samplers import quantum
from ..scenes import load_scene
from ..scenes.units import check_units
from .assemble import Passes, assemble_capture, build_record, versions
from .checkpoint import Checkpoint, partial_lock, resume_parts
from .estimate import PILOT_PASSES, rms
from .integrate import CaptureInterrupted, Run, integrate
from .optics.diffraction import decide, diffract, preview_sampling
from .plan import CapturePlan, plan_capture
from .render_time import estimate_capture, in_overall, metered, planned_steps, say
from .spec import CaptureSpec
from .steps import exposure_windows, fine_step_sampler, plan_exposure
from .truth import render_truth


def render_capture(
    spec: CaptureSpec | CapturePlan,
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
    :func:`~pacam_render.exposure.steps.plan_steps` (see :mod:`.integrate`).

    Parameters
    ----------
    spec : CaptureSpec or CapturePlan
        What to capture; a :class:`~.plan.CapturePlan` already resolved
        (:func:`~.plan.plan_capture`, as ``pacam render`` does before it opens its output) is
        rendered as it is, a spec is resolved first. Either way the camera is resolved once.
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
        ``render_error.planned_spp`` predicts the samples the target needs, and
        ``render_error.predicted_seconds`` the time the rest takes (one step of a main pass
        timed). No ground truth.
    keep_partial : bool, optional
        Keep the finished passes in ``partial_dir`` when the capture is done, for the caller
        to remove once the capture is safely written (a failed write then loses no rendering:
        the same capture resumes from them at once).

    Returns
    -------
    Capture
        The image, (height, width, 3) float64 ((height, width) for a grey capture: its spec's
        ``grey``, or a mono variant) in radiance x (open area / full aperture) x
        (exposure / 45 ms); its per-pixel Monte Carlo sigma (``mc_sigma``); the per-pattern
        images of a moving scene when ``spec.per_pattern`` is set; the ground-truth layers in
        ``extra_layers``, with their legend in ``record.objects``; and the
        :class:`~pacam_render.capture.record.CaptureRecord`, whose ``render_error`` states
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
    Selects and activates a Mitsuba variant: the mono one for ``spec.grey``; under a mono
    ``PACAM_VARIANT`` the recorded spec says ``grey`` too. The fastest image speed is taken over
    the paper's t in [-T, T] (the exposure is 2T), and each step renders the geometry at a
    random time in it. Same-seed captures are bit-identical (:mod:`pacam_render.render.passes`).
    """
    given = spec if isinstance(spec, CapturePlan) else None
    check_budget(spec.spec if given else spec, max_samples, truth, target is not None)
    lock = partial_lock(partial_dir)
    with lock, warnings.catch_warnings(record=True) as caught, deferred_signals() as flag:
        warnings.simplefilter("always", PacamWarning)
        plan = given if given is not None else plan_capture(spec)
        plan.replay_notes()  # the camera's notes go in the record, first, as they always have
        run = Run(partial_dir, progress, save_every_s, stop_after_steps, max_steps, flag)
        run = replace(run, max_samples=max_samples, pilot_only=pilot_only and target is not None)
        plan, run = _decide(plan, description, run, truth, target)
        cap = _render(plan, description, run, truth, target, keep_partial)
    cap.record.notes = _replay(caught)
    return cap


def _decide(plan: CapturePlan, description, run: Run, truth: bool, target):
    """(the plan as it renders, the run): the passes' sampler for fine time steps
    (:func:`_fine_steps`; ``sharp`` keeps the one asked), the estimate said, and diffraction
    decided (``auto`` renders its preview)."""
    scene = description if description is not None else load_scene(plan.spec.scene)
    run = replace(run, truth_sampler=plan.spec.sampler)  # sharp is still: as asked
    plan = _fine_steps(plan, scene, run, target)  # before the estimate and auto's preview
    if run.progress:
        _announce(plan, description, run, truth, target)
    return plan.with_diffraction(*_diffraction_choice(plan, description, run, target)), run


def _announce(plan: CapturePlan, description, run: Run, truth: bool, target) -> None:
    """Say the capture's predicted time before any render
    (:mod:`pacam_render.exposure.render_time`), on stderr; inside a command's overall bar, which
    said its own, nothing."""

    if in_overall():
        return
    est = estimate_capture(plan, description, target is not None, truth, run.max_steps)
    then = "; the noise target plans the rest from it" if target is not None else ""
    say(f"estimate: {est.describe()}{then}")


def preview_scene(desc):
    """The scene ``auto``'s preview renders: frozen at t = 0, so that a pass is one render
    whatever the motion (its cost was the time steps'). Motion only lowers the image's high
    frequencies, where diffraction acts, and adds the poses' noise to the capture's sigma, so the
    frozen preview's effect and its threshold err towards including diffraction."""
    return replace(desc, motions={}) if not desc.is_static else desc


def _diffraction_choice(plan: CapturePlan, description, run: Run, target) -> tuple[bool, str]:
    """``spec.diffraction`` resolved: (in the capture, the decision in words). ``auto`` renders
    a short geometric preview (:func:`preview_scene`: 2 passes with the capture's own sampler,
    no truth) and measures diffraction's effect on it with the post-process
    (:func:`~pacam_render.exposure.optics.diffraction.diffract`, its Monte Carlo share removed):
    included unless below the noise target, or without one below the Monte Carlo sigma the
    capture will reach: the preview's, scaled by the square root of its samples over those the
    capture's passes will take (:func:`~pacam_render.exposure.render_time.planned_spp`, every
    pattern's step counted). An ``independent`` preview overstated a capture's ``ldsampler``
    sigma 1.4-1.7x, and ``spec.spp`` understated a 32-pattern design's samples 2x (issue 56)."""

    spec = plan.spec
    if not plan.lens:
        return False, "not applicable: a pinhole"
    if spec.diffraction != "auto":
        return decide(spec.diffraction, 0.0, 0.0, "")  # as asked

    t0 = time.perf_counter()
    desc = description if description is not None else load_scene(spec.scene)
    n, passes = preview_sampling(spec.sampler, planned_steps(plan, desc, run.max_steps))
    quick = plan.with_spec(diffraction="off", spp=n * passes, passes=passes,
                           per_pattern=False).with_diffraction(False, "preview")  # fmt: skip
    frozen = preview_scene(desc)
    quiet = replace(run, progress=False, partial_dir=None, pilot_only=False, stop_after_steps=None)
    if run.progress:  # a preview is announced: it runs before the capture's own bar
        say(f"diffraction auto: rendering a short geometric preview first ({n * passes} spp, the "
            "scene at t = 0, no truth layers) to measure diffraction's effect")  # fmt: skip
    with warnings.catch_warnings():  # the preview's own notes are not the capture's
        warnings.simplefilter("ignore", PacamWarning)
        try:
            pre = _render(quick, frozen, quiet, False, None, False)
        except CaptureInterrupted as exc:  # its steps are not the capture's: none to resume
            raise CaptureInterrupted(
                "interrupted during the preview that diffraction 'auto' renders, before the "
                "capture began; nothing to resume",
                signum=exc.signum,
            ) from None
    var = pre.mc_sigma**2
    d = diffract(pre.image, {}, var, plan.cam, spec.mode, plan.pitch_mm)
    if target is not None:
        threshold, why = float(target.sigma(pre.image, pre.record)), "the noise target"
    else:
        spp = plan.spec.passes * sum(s.spp for s in planned_steps(plan, desc, run.max_steps))
        threshold = rms(var) * (pre.record.effective_spp / spp) ** 0.5
        why = f"the Monte Carlo sigma predicted at {spp} spp"
    on, text = decide("auto", d.record["effect_rms"], threshold, why)
    took = time.perf_counter() - t0
    n = pre.record.effective_spp
    return on, f"{text} (both from a {n} spp geometric preview at t = 0, {took:.1f} s)"


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

    The samples counted are the least the passes render, as a static scene's passes round
    ``spec.spp`` (``spec.passes`` passes, each a multiple of the sampler's smallest render); a
    capture rendered to a noise target (``targeted``) counts its two pilot passes of that
    smallest render. A moving scene's time steps round them further, which
    :func:`~.progress.check_samples` counts once the steps are planned, before any render.

    Raises
    ------
    ParameterError
        Naming ``--max-samples``, or ``--width`` and ``--height`` for memory (about 210 bytes
        per pixel, plus 24 per pixel and pattern with ``per_pattern`` and 96 with ``truth``).
    """

    w, h = spec.image_size
    pixels = w * h
    per_px = 208 + (24 * paper.N_PATTERNS if spec.per_pattern else 0) + (96 if truth else 0)
    check_memory(f"a {w}x{h} capture", per_px * pixels, "`width`/`height` or `crop`")
    if pixels > MAX_WAVEFRONT:
        raise ParameterError(
            f"a {w}x{h} image has more than Mitsuba's {MAX_WAVEFRONT} samples per pass at 1 "
            "spp; reduce `width`/`height` or `crop`"
        )
    q = quantum(spec.sampler)
    least = f"passes of at least {q} spp ({spec.sampler})"
    if targeted:
        spp = PILOT_PASSES * q
        why = f"the pilot of this noise target ({PILOT_PASSES} {least}; "
    else:
        per = -(-spec.spp // spec.passes)  # a pass's spp, as fixed_schedule takes it
        spp = spec.passes * q * -(-per // q)
        why = "this capture (" + (
            f"{spec.passes} {least}, take {spp} spp where `spp` {spec.spp} was asked; "
            if spp > spec.spp
            else ""
        )
    hint = "; or lower `passes`" if spp > spec.spp and not targeted else ""
    check_count(
        f"samples of {why}{spp} spp x {w} x {h} px)", spp * pixels, max_samples, "max_samples",
        hint,
    )  # fmt: skip


def _render(plan: CapturePlan, description, run: Run, truth: bool, target, keep: bool) -> Capture:
    """The capture of a plan whose diffraction is decided (:func:`_diffraction_choice`); its
    work and seconds go in this machine's history of renders
    (:func:`~pacam_render.exposure.render_time.metered`)."""

    with metered(plan.variant):
        return _render_plan(plan, description, run, truth, target, keep)


def _render_plan(plan: CapturePlan, description, run: Run, truth, target, keep: bool) -> Capture:
    """:func:`_render`'s work."""

    spec, design, cam, variant = plan.spec, plan.design, plan.cam, plan.variant
    params = plan.sensor_params()
    desc = description if description is not None else load_scene(spec.scene)
    t_start = time.perf_counter()
    scene = desc.load(sensor=sensor_entry(spec, cam, params, cam.exposure_ms))
    sensor = scene.sensors()[0]
    check_units(scene, design)  # a scene in metres renders near-black with no other word
    run.check_signal()
    exp, speed = plan_exposure(scene, sensor, desc, design, cam, spec, run.max_steps)
    aperture = None if spec.mode == "reference" else sensor.plan
    record = build_record(plan, params, aperture, 0.0, {})
    steps_plan = {"windows": exp.windows, "target": None if target is None else target.to_json()}
    parts = resume_parts(plan.key(), scene, desc, steps_plan, versions(), variant)
    store = Checkpoint(None if run.partial_dir is None else Path(run.partial_dir), parts)
    with exp.animator or nullcontext():  # back to t = 0 however it ends (SceneAnimator)
        prog = integrate(exp, spec, run, store, target, record, f"{spec.mode} {spec.scene}")
    render_s = time.perf_counter() - t_start + prog.seconds_before  # earlier sessions' too
    if not run.pilot_only:  # a pilot stops short of its target by design
        _note_samples(spec, exp, prog, target)
    if exp.moving:  # the whole exposure's window for the ground truth
        sensor.configure(time_window=None)
    if run.pilot_only or keep or truth:  # what is done stays on disk until it is not needed
        store.save(prog.state(), prog.arrays())
    truth = truth and not run.pilot_only
    layers, objects, sharp = _truth(scene, desc, spec, design, run, prog, record, store, truth)
    if spec.mode == "reference" and truth:
        layers["sharp"], sharp = prog.stats.mean(), prog.stats
    if not run.pilot_only and not keep:
        store.clear()
    seconds = time.perf_counter() - t_start + prog.seconds_before
    n_steps = exp.steps_per_pass(prog.sched.groups[-1][0])
    passes = Passes(
        prog.stats, aperture, seconds, render_s, spec.sampler, n_steps,
        time_steps_per_pass=n_steps if exp.moving else 0,
        time_sampling=TIME_SAMPLING[exp.moving],
        n_geometry_updates=exp.animator.n_updates if exp.moving else 0,
        resumed_from_step=prog.resumed_from if exp.moving else None,
        fastest_image_speed_px_per_ms=speed if exp.moving else None,
        schedule=prog.sched, predicted_seconds=prog.predicted_s, sharp=sharp,
    )  # fmt: skip
    return assemble_capture(plan, desc, passes, layers, objects, target)


def _fine_steps(plan: CapturePlan, desc, run: Run, target) -> CapturePlan:
    """The plan, with ``independent`` samples where a fixed capture's passes are too small
    for its sampler to keep every time step within ``max_step_px``
    (:func:`~.steps.fine_step_sampler`), said in a note."""

    spec = plan.spec
    if target is not None or desc.is_static or spec.mode == "reference" or not plan.lens:
        return plan
    windows, _ = exposure_windows(desc, plan.design, plan.cam, spec, plan.aperture(),
                                  run.max_steps)  # fmt: skip
    per = -(-spec.spp // spec.passes)
    sampler = fine_step_sampler(spec.sampler, per, windows)
    if sampler == spec.sampler:
        return plan
    q = quantum(spec.sampler)
    note(
        f"sampler {sampler} instead of {spec.sampler}: a pass of {per} spp cannot give each of "
        f"the {len(windows)} time steps (max_step_px {spec.max_step_px:g}) {spec.sampler}'s "
        f"{q} spp, and steps joined beyond max_step_px put their time noise in a few "
        "image-wide patterns that the passes' spread states at random; raise `spp` to "
        f"{q * len(windows) * spec.passes} to keep {spec.sampler}"
    )
    return replace(plan, spec=replace(spec, sampler=sampler))  # the camera is unchanged


TIME_SAMPLING = {
    True: "stratified random times, one per step and pass: unbiased, their noise is in mc_sigma",
    False: "none: every ray samples the whole exposure",
}
"""``render_error.time_sampling`` of a direct render, for a moving scene and a still one."""


def _note_samples(spec: CaptureSpec, exp, prog, target) -> None:
    """Say when the passes took more samples than asked, or a target was not met."""
    sched = prog.sched
    if target is None and prog.stats.spp > spec.spp:
        per = "time step" if exp.moving else "pass"
        note(
            f"{spec.passes} passes of at least {exp.quantum} spp per {per} ({spec.sampler}) take "
            f"{prog.stats.spp} spp where {spec.spp} were asked"
            + ("; each pattern needs one step" if exp.moving else "")
        )
    if target is not None and not sched.met:
        note(
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
        asked = replace(spec, sampler=run.truth_sampler or spec.sampler)
        return render_truth(scene, desc, asked, design, spec.mode != "reference", quiet, goal)
    except CaptureInterrupted as exc:
        where = run.partial_dir if store.folder is not None else None
        raise CaptureInterrupted(
            "interrupted while rendering the ground truth; the capture's steps are "
            + (f"saved in {where}: run the same command again to resume" if where else "lost"),
            exc.done,
            exc.total,
            exc.signum,
        ) from None


def write_capture(cap: Capture, out, force: bool = False, error_layer: bool = False) -> list[Path]:
    """capture.exr (float32 layers), capture.png (sRGB preview), capture.json.

    Parameters
    ----------
    cap : Capture
        The capture to write.
    out : str or pathlib.Path
        The output folder (created if missing).
    force : bool, optional
        Overwrite existing files (default: refuse them).
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
    (``units``; :func:`~pacam_render.capture.files.read_capture` reads them on one scale).
    Each file is written to a temporary file and renamed.
    """

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
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
