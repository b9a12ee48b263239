"""A finished capture's record: the :class:`~pacam_render.capture.record.CaptureRecord` built
from its plan, sensor and passes, with its render error (the Monte Carlo sigma and its cost)
and each object's fit to the design.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..capture.record import CaptureRecord
from ..limits import note
from ..model import paper

REFERENCE_EXPOSURE_MS = paper.EXPOSURE_MS
"""Pixel values are scaled to this exposure: a capture's brightness is proportional to the
light it collects, and every mode compares directly."""


def versions() -> dict:
    """The versions that make a capture: the package's, Mitsuba's, Dr.Jit's and NumPy's."""
    import drjit
    import mitsuba

    from .. import __version__

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
    from .design_fit import fit_notes, object_fit

    if mode == "reference" or not objects or "depth" not in layers:
        return None
    fit = object_fit(layers, objects, cam, mode)
    for line in fit_notes(fit, cam, mode):
        note(line)
    return fit


def render_error_summary(prog, exp, spec, seconds, objects, ids, record, sharp) -> dict:
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
