"""One assembly for every producer of captures: a plan and its rendered passes into a
:class:`~pacam_render.capture.result.Capture`.

A direct render (:func:`~pacam_render.exposure.direct.render_capture`) and a synthesis from a
light-field store (:func:`~pacam_render.lightfield.synthesis.synthesize`) hand their passes to
:func:`assemble_capture` as :class:`Passes`, and it runs the one sequence: the record
(:func:`build_record`), each object's fit to the design (:mod:`.design_fit`), the render error
(:func:`render_error`), the relative illumination's map and record, then diffraction and the
physics error budget (:func:`~pacam_render.exposure.optics.budget.finish_optics`). So the two
producers' records carry the same keys and the same meanings.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import __version__
from ..capture.record import CaptureRecord
from ..capture.render_error import RenderError
from ..capture.result import Capture
from ..limits import note
from ..model import paper
from .camera import illumination_map, illumination_record
from .design_fit import fit_notes, object_fit
from .estimate import PassStats, error_summary, rms
from .optics.budget import OpticsContext, finish_optics
from .truth import TRUTH_LAYERS

REFERENCE_EXPOSURE_MS = paper.EXPOSURE_MS
"""Pixel values are scaled to this exposure: a capture's brightness is proportional to the
light it collects, and every mode compares directly."""


@dataclass(frozen=True)
class Passes:
    """What a producer rendered, as :func:`assemble_capture` takes it.

    Attributes
    ----------
    stats : PassStats
        The passes: their mean image, per-pixel variance and per-pattern images.
    aperture : AperturePlan or None
        The sensor's aperture plan (:class:`~pacam_render.render.plan.AperturePlan`; its
        mean weight is the record's ``light_factor``); None for the pinhole reference.
    seconds : float
        The capture's seconds in all (the record's ``render_seconds``), s.
    render_seconds : float
        The passes' seconds (``render_error.seconds``), s.
    sampler : str
        Mitsuba's sampler, or ``light-field store``.
    n_steps : int
        Time steps of the record (a pass's steps, or the store's).
    time_steps_per_pass : int
        A moving scene's steps per pass; 0 where one render covers the exposure.
    time_sampling : str
        How the exposure's time is sampled, in words.
    n_geometry_updates : int
        Geometry poses set (0 for a still scene or a synthesis).
    resumed_from_step, fastest_image_speed_px_per_ms : optional
        A moving render's resume point and fastest image speed (px/ms).
    schedule : PassSchedule, optional
        The pass planner of a capture rendered to a noise target (its target, whether it was
        met, and the samples it planned).
    predicted_seconds : float, optional
        A pilot's prediction of the rest of its render, s.
    sharp : PassStats, optional
        The ``sharp`` truth layer's passes (their sigma goes in the render error).
    sharp_mc_sigma : float, optional
        That sigma where the passes are not at hand (a store's truth records it).
    extra : dict
        Record keys beside the fields (a synthesis's ``lightfield``).
    """

    stats: PassStats
    aperture: object
    seconds: float
    render_seconds: float
    sampler: str
    n_steps: int
    time_steps_per_pass: int
    time_sampling: str
    n_geometry_updates: int = 0
    resumed_from_step: int | None = None
    fastest_image_speed_px_per_ms: float | None = None
    schedule: object = None
    predicted_seconds: float | None = None
    sharp: PassStats | None = None
    sharp_mc_sigma: float | None = None
    extra: dict | None = None

    def steps(self) -> dict:
        """The record's step fields."""
        return {
            "n_steps": self.n_steps,
            "n_geometry_updates": self.n_geometry_updates,
            "effective_spp": self.stats.spp,
            "resumed_from_step": self.resumed_from_step,
            "fastest_image_speed_px_per_ms": self.fastest_image_speed_px_per_ms,
        }


def assemble_capture(plan, desc, passes: Passes, layers: dict, objects, target=None) -> Capture:
    """The capture of ``plan`` from its rendered ``passes`` (module docstring).

    Parameters
    ----------
    plan : CapturePlan
        The capture, resolved, with its diffraction decided.
    desc : SceneDescription
        The scene it shows (its integrator sizes the bounces' budget entry).
    passes : Passes
        What the producer rendered.
    layers : dict
        The ground-truth layers (:data:`~.truth.TRUTH_LAYERS`; others are dropped).
    objects : dict or None
        The ``object_id`` legend.
    target : NoiseTarget, optional
        The capture's noise target (its sensor is the budget's reference noise).

    Returns
    -------
    Capture
        The image (diffracted where decided), its pattern images, record, layers (with
        ``relative_illumination`` where it is on) and per-pixel Monte Carlo sigma.
    """
    spec, cam = plan.spec, plan.cam
    record = build_record(plan, plan.sensor_params(), passes.aperture, passes.seconds,
                          passes.steps())  # fmt: skip
    record.objects = objects
    record.design_fit = record_design_fit(layers, objects, cam, spec.mode)
    record.render_error = render_error(passes, objects, layers.get("object_id"), record)
    record.extra.update(passes.extra or {})
    layers = {k: layers[k] for k in TRUTH_LAYERS if k in layers}
    ri_map = illumination_map(spec, cam, plan.pitch_mm)  # None when off
    record.relative_illumination = illumination_record(spec, cam, ri_map)
    if ri_map is not None:
        layers["relative_illumination"] = ri_map
    stats = passes.stats
    patterns = stats.pattern_means() if spec.per_pattern else {}
    ctx = OpticsContext(record, target, layers.get("sharp"), layers.get("depth"))
    optics = finish_optics(plan, desc, stats.mean(), patterns, stats.variance(), ctx)
    record.optics_error = optics.block
    return Capture(optics.image, optics.patterns, record, layers, np.sqrt(optics.variance))


def render_error(passes: Passes, objects, ids, record: CaptureRecord) -> RenderError:
    """The record's ``render_error``: the Monte Carlo sigma (capture units), its cost, and the
    time steps' error (none: random times make them noise, counted in the sigma)."""
    summary = error_summary(passes.stats, objects, ids)
    lf = record.light_factor
    err = RenderError(
        **summary,
        mc_sigma_white_units=summary["mc_sigma"] / lf if lf > 0 else None,
        sampler=passes.sampler,
        seconds=round(passes.render_seconds, 3),
        time_steps_per_pass=passes.time_steps_per_pass,
        time_step_bias=0.0,
        time_sampling=passes.time_sampling,
    )
    sched = passes.schedule
    if sched is not None and sched.target_sigma is not None:
        err.target_sigma, err.target_met = sched.target_sigma, bool(sched.met)
        err.planned_spp = sched.planned_spp
    if passes.predicted_seconds:
        err.predicted_seconds = round(passes.predicted_seconds, 3)
    if passes.sharp is not None:
        err.sharp_mc_sigma = rms(passes.sharp.variance())
    elif passes.sharp_mc_sigma is not None:
        err.sharp_mc_sigma = passes.sharp_mc_sigma
    return err


def versions() -> dict:
    """The versions that make a capture: the package's, Mitsuba's, Dr.Jit's and NumPy's."""
    import drjit  # here, not at the top: importing the package loads no renderer
    import mitsuba

    return {
        "pacam_render": __version__,
        "mitsuba": mitsuba.__version__,
        "drjit": drjit.__version__,
        "numpy": np.__version__,
    }


def build_record(plan, params: dict, aperture, seconds: float, steps: dict) -> CaptureRecord:
    """The capture's record: the one place that builds it, from its
    :class:`~.plan.CapturePlan`, the sensor's parameters and the sensor's
    :class:`~pacam_render.render.plan.AperturePlan` (None for the pinhole reference), whatever
    produced the capture (a render, or a light-field store)."""
    spec, design, cam, variant = plan.spec, plan.design, plan.cam, plan.variant
    contrast = params.get("lcos_contrast")  # the light the "off" pixels leak counts too
    weight = 1.0 if spec.mode == "reference" else float(aperture.mean_weight(contrast))
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
        design=design.inputs(),
        optics=cam.summary(),
        coded_design=design.summary(),
        sensor_params={k: v for k, v in params.items() if not hasattr(v, "shape")},
        exposure_ms=cam.exposure_ms,
        reference_exposure_ms=REFERENCE_EXPOSURE_MS,
        light_factor=weight,
        render_seconds=seconds,
        variant=variant,
        versions=versions(),
        **steps,
    )


def record_design_fit(layers: dict, objects: dict | None, cam, mode: str) -> dict | None:
    """Each object against the design's depth and speed range (:mod:`.design_fit`), noted."""
    if mode == "reference" or not objects or "depth" not in layers:
        return None
    fit = object_fit(layers, objects, cam, mode)
    for line in fit_notes(fit, cam, mode):
        note(line)
    return fit
