"""The optics after the rays: a capture's diffraction and its physics error budget.

:func:`finish_optics` runs once the render has met its error: it adds the openings'
diffraction when the capture's ``diffraction`` setting asks for it (``auto`` decides from the
effect's measured size, :mod:`pacam_render.exposure.optics.diffraction`), and writes the record's
``optics_error`` (:mod:`pacam_render.capture.optics_error`) with the sizes of what is left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...capture import optics_error as oe
from ...errors import ParameterError
from ...model.illumination import relative_illumination_map
from ...model.modes import mode as mode_of
from ...render.ray_diffraction import (
    MAX_LOST,
    RayDiffractionSpec,
    inverse_table,
    radial_table,
    sensor_properties,
)
from ...sensor.apply import sensor_sigma
from ...sensor.model import SensorModel
from ...sensor.presets import mono_preset
from ...sensor.radiometry import DEFAULT_LIGHT_LEVEL
from ...wave.patterns import channel_wavelengths_nm, shows_bitmaps
from ..camera import switched_patterns
from ..estimate import rms
from .diffraction import diffract
from .wave_residual import occlusion_rms, residual_rms


@dataclass
class Optics:
    """What :func:`finish_optics` returns: the image, its pattern windows and Monte Carlo
    variance (diffracted when included), and the record's ``optics_error`` block."""

    image: np.ndarray
    patterns: dict
    variance: np.ndarray
    block: dict


def reference_noise(spec, design, record, image, target) -> tuple[float | None, str]:
    """The sensor's temporal noise at the capture's mean level, its units, and which sensor:
    a noise target's (its lowest), else the design's preset or the ICX285 at the default light
    level (``pacam render --sensor`` replaces it with the capture's own)."""

    if target is not None and hasattr(target, "sensor_sigmas"):
        return min(target.sensor_sigmas(image, record)), "the noise target's sensor"
    preset = design.sensor_preset or "grasshopper-icx285"
    preset = mono_preset(preset) if spec.grey else preset
    model = SensorModel.from_preset(preset)
    light = DEFAULT_LIGHT_LEVEL if model.shot_noise else None
    lf = record.light_factor
    if lf <= 0:
        return None, preset
    level = float(np.mean(image)) / lf
    where = f"{preset}" + (f" at {light:g} photons/px/ms" if light else "")
    return sensor_sigma(record, model, light, level) * lf, where


def _diffraction(plan, image, patterns, variance):
    """(the post-processed capture or None, whether diffraction is in the capture, the
    block's ``diffraction``): in the rays (disc openings), after the render (a bitmap
    schedule's patterns), or left out and its effect measured by the post-process."""
    spec, cam = plan.spec, plan.cam
    head = {"setting": spec.diffraction}
    if not plan.lens:
        return None, False, {**head, "decision": "not applicable: a pinhole"}
    on, decision = plan.diffraction
    head["decision"] = decision
    if on and not shows_bitmaps(cam, spec.mode):
        return None, True, {**head, **rays_record(spec, cam, plan.pitch_mm)}
    try:
        d = diffract(image, patterns, variance, cam, spec.mode, plan.pitch_mm)
    except ParameterError as exc:
        if on:
            raise
        # left out, and too wide to measure (a slit of a few LCoS pixels): say so, not fail
        return None, False, {**head, "how": f"not measured: {exc}"}
    return (d if on else None), on, {**head, **d.record}


def exact_in_rays(spec) -> bool:
    """Whether a disc capture's rays take the exact defocused PSF
    (:mod:`pacam_render.render.kernels.defocus_draw`): not with a leaky LCoS or a pixel grid, whose
    rays keep the geometric lens point and the Airy draw."""
    contrast = spec.lcos_contrast
    return spec.lcos_fill_factor is None and (contrast is None or math.isinf(contrast))


def rays_record(spec, cam, pitch_mm: float) -> dict:
    """How the rays diffract (:mod:`pacam_render.render.ray_diffraction`,
    :mod:`pacam_render.render.kernels.defocus_draw`)."""

    params = diffraction_params(spec, cam, True, pitch_mm)
    rays = RayDiffractionSpec(params["diffraction_wavelengths"], params["pupil_distance"], pitch_mm)
    lost = radial_table(MAX_LOST)[2]
    l1 = inverse_table(MAX_LOST)[1]
    how = (
        "in the rays: the opening's exact defocused (Fresnel) PSF at the depth each camera "
        "ray's probe meets, per colour channel (beyond 4 waves of defocus: the Airy draw)"
        if exact_in_rays(spec)
        else "in the rays: each film position moved by a draw from the opening's Airy "
        "pattern, per colour channel"
    )
    return {
        "how": how,
        "ray_psf": "exact" if exact_in_rays(spec) else "fraunhofer",
        "wavelengths_nm": list(rays.wavelengths_nm),
        "lambda_n_px": rays.lambda_n_px(cam.R_mm),
        "pixel_pitch_mm": pitch_mm,
        "airy_lost": lost,
        "airy_table_l1": l1,
    }


_AIRY_RAYS = (
    "geometric defocus x Fraunhofer (L1 to the exact defocused PSF: 0 in focus, 0.25 at "
    "r = 2 px, 0.20 at 8 px; tests/render/test_exact_defocus.py)"
)
_EXACT_RAYS = (
    "exact paraxial PSF over surfaces at one depth (L1 <= 0.004 to an independent Fresnel "
    "computation; tests/render/test_exact_defocus.py); at an occluding edge the drawn ray may "
    "meet another surface than the probe, and no ray method is exact there"
)
_HOW_SIZED = {
    _AIRY_RAYS: "measured: (exact paraxial - rays' kernel) * sharp, RMS over the window "
    "(exposure/optics/wave_residual.py)",
    _EXACT_RAYS: "scale: the whole wave effect, (exact - geometric kernel) * sharp, within the "
    "kernel's reach of a depth jump, RMS over the window (what an occluder's edge can change; "
    "not a strict bound; exposure/optics/wave_residual.py)",
}


def _diffraction_entry(
    info: dict, included: bool, residual: float | None = None, approx: str = _AIRY_RAYS
) -> dict:
    if "effect_rms" not in info and not included:
        if info.get("how", "").startswith("not measured"):  # unknown, not nothing
            return oe.entry(False, info["decision"], None, info["how"])
        return oe.entry(False, info["decision"], 0.0)
    if included and residual is not None:  # what the rays' method leaves out
        return oe.entry(True, info["how"], residual, _HOW_SIZED[approx], approximation=approx,
                        residual=True)  # fmt: skip
    if included:
        return oe.entry(True, info["how"], approximation=approx)
    return oe.entry(
        False,
        "left out: geometric optics through the opening",
        info["effect_rms"],
        "measured: the post-process's change, Monte Carlo noise removed",
        approximation=approx,
    )


@dataclass(frozen=True)
class OpticsContext:
    """What :func:`finish_optics` needs of a capture beside its plan and image.

    Attributes
    ----------
    record : CaptureRecord
        The capture's record so far (its light factor, exposure and relative illumination).
    target : NoiseTarget or None
        The capture's noise target: its sensor is the budget's reference noise.
    sharp, depth : numpy.ndarray or None
        The ``sharp`` and ``depth`` truth layers, which size what the rays' diffraction
        leaves out (:mod:`.wave_residual`); None without truth.
    """

    record: object
    target: object = None
    sharp: np.ndarray | None = None
    depth: np.ndarray | None = None


def finish_optics(plan, desc, image, patterns, variance, ctx: OpticsContext) -> Optics:
    """Diffraction as ``plan.diffraction`` decided it, and the ``optics_error`` block (module
    docstring), for the capture ``plan`` (a :class:`~pacam_render.exposure.plan.CapturePlan`)
    of the scene ``desc``."""
    spec, cam, rec = plan.spec, plan.cam, ctx.record
    d, included, info = _diffraction(plan, image, patterns, variance)
    if d is not None:
        image, patterns, variance = d.image, d.patterns or patterns, d.variance
        info["mc_sigma_after"] = rms(variance)
    residual, approx = _rays_residual(plan, included, ctx)
    w, h = spec.image_size
    cos4 = relative_illumination_map("cos4", w, h, cam.fov_deg, spec.crop) if plan.lens else None
    lcos = plan.optics_params
    effects = {
        "diffraction": _diffraction_entry(info, included, residual, approx),
        "relative_illumination": oe.relative_illumination_entry(
            image, cos4, rec.relative_illumination
        ),
        "lcos_leakage": oe.leakage_entry(
            image, full_over_coded(rec), lcos.get("lcos_contrast"), spec.lcos_contrast
        ),
        "lcos_grid": oe.grid_entry(image, spec.lcos_fill_factor if included else None),
        "lcos_switching": oe.switching_entry(
            image,
            switched_patterns(plan.mode_params, cam),
            cam.exposure_ms,
            lcos.get("lcos_switching"),
            spec.lcos_switching_ms,
        ),  # fmt: skip
        "bounces": oe.bounces_entry(image, spec.scene, getattr(desc, "integrator", None)),
    }
    block = {"diffraction": info, "effects": effects}
    noise, where = reference_noise(spec, plan.design, rec, image, ctx.target)
    oe.add_ratios(block, noise, where, own=ctx.target is not None)
    return Optics(image, patterns, variance, block)


def _rays_residual(plan, included: bool, ctx: OpticsContext) -> tuple[float | None, str]:
    """What the rays' diffraction leaves out (RMS, :mod:`.wave_residual`) and the method's
    approximation in words."""
    spec, cam = plan.spec, plan.cam
    if not included or shows_bitmaps(cam, spec.mode):
        return None, _AIRY_RAYS
    args = (cam, spec.mode, plan.pitch_mm, ctx.record.light_factor)
    if exact_in_rays(spec):
        return occlusion_rms(ctx.sharp, ctx.depth, *args), _EXACT_RAYS
    return residual_rms(ctx.sharp, *args), _AIRY_RAYS


def diffraction_params(spec, cam, on: bool, pitch_mm: float) -> dict:
    """The sensor's parameters that put diffraction in the rays: none when off, for the
    pinhole, or for a bitmap schedule's patterns (diffracted after the render); ``pitch_mm``
    is the capture's pixel pitch (:attr:`~pacam_render.exposure.plan.CapturePlan.pitch_mm`)."""
    if on and spec.lcos_fill_factor is not None and shows_bitmaps(cam, spec.mode):
        raise ParameterError(
            "lcos_fill_factor: the grid's orders are rendered through disc openings; a bitmap "
            "schedule's capture is diffracted after the render, without them"
        )
    if not on or mode_of(spec.mode).schedule is None or shows_bitmaps(cam, spec.mode):
        return {}

    waves = channel_wavelengths_nm(1 if spec.grey else 3)
    grid = {} if spec.lcos_fill_factor is None else {"lcos_fill_factor": spec.lcos_fill_factor}
    return {**sensor_properties(cam, waves, pitch_mm), **grid}


def full_over_coded(rec) -> float:
    """The full aperture's light over the capture's, for the same exposure: (E / E_ref) /
    light_factor (1 for a full-aperture capture, whose leakage is nil)."""
    lf = rec.light_factor
    if lf <= 0:
        return 1.0
    return (rec.exposure_ms / rec.reference_exposure_ms) / lf
