"""The camera a capture uses: the preset's design at the capture's size (solved to cover a
speed, or read from a schedule file), the mode's camera and sensor parameters from the table of
:mod:`pacam_render.model.modes`, and notes on what the mode leaves unused.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..limits import note
from ..model.camera import CameraDesign, preset
from ..model.design import solve
from ..model.design_file import resolve_design
from ..model.illumination import (
    film_tan_max,
    relative_illumination_map,
    thin_lens_relative_illumination,
)
from ..model.modes import DESIGNED_REFUSED, MODES, capture_camera, mode, sensor_params
from ..model.schedule import RASKAR_2006_CODE, flutter_code
from ..model.schedule_file import apply_schedule, read_schedule
from .spec import CaptureSpec


def capture_design(spec: CaptureSpec) -> CameraDesign:
    """The design's (or preset's) optics at the capture's resolution (px quantities scale
    with the width).

    With ``cover_px_per_ms`` (a speed in the preset's own pixels), the design solver first
    picks the defocus that makes that speed motion-invariant at the preset's F-number, or at
    ``f_number``, or with the defocus radius ``r_px`` (preset px). ``object_depth_mm`` is the
    depth the design is made for (default the preset's: 500 mm for the prototype).

    Parameters
    ----------
    spec : CaptureSpec
        Uses ``design`` (a design file, else ``preset``), ``cover_px_per_ms`` (px/ms),
        ``schedule`` and ``width`` and ``height`` (px).

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
    return scaled_design(spec, full_design(spec, **depth))


def scaled_design(spec: CaptureSpec, base: CameraDesign) -> CameraDesign:
    """:func:`capture_design` from the design as read (``base``, :func:`full_design` with the
    spec's depth): solved or scheduled as the spec asks, its LCoS rate checked, at the
    capture's size."""
    if spec.cover_px_per_ms is not None:
        base = solve(spec.cover_px_per_ms, f_number=spec.f_number, r_px=spec.r_px, base=base)
    if spec.schedule is not None:
        sched = read_schedule(spec.schedule)
        if spec.object_depth_mm is None and "object_depth_mm" in sched:
            base = base.with_(object_depth_mm=sched["object_depth_mm"])
        base = apply_schedule(base, sched, spec.schedule)
    base.check_lcos_rate()
    return base.with_(width_px=spec.width, height_px=spec.height)


def full_design(spec: CaptureSpec, **overrides) -> CameraDesign:
    """The design a capture starts from, at its own full sensor size: ``spec.design``
    (:func:`~pacam_render.model.design_file.resolve_design`), else the preset."""
    if spec.design is None:
        return preset(spec.preset, **overrides)

    return resolve_design(spec.design, **overrides)


def mode_camera(design: CameraDesign, mode: str) -> tuple[CameraDesign, dict]:
    """The camera a mode uses (for its analytic PSF) and the sensor's schedule parameters,
    both from the table of :mod:`pacam_render.model.modes`.

    Parameters
    ----------
    design : CameraDesign
        The coded design (:func:`capture_design`).
    mode : str
        A capture mode, one of :data:`~pacam_render.model.modes.MODES`.

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
        design = design.with_(pattern_centres_mm=None, pattern_masks=None, name=text)
    cam = capture_camera(design, mode)
    return cam, sensor_params(cam, mode)


def illumination_params(spec: CaptureSpec, pitch_mm: float) -> dict:
    """The sensor's relative-illumination parameters for a capture.

    None when ``off`` (the plugin's default: its kernels, and the record's ``sensor_params``,
    stay as they were) or for the pinhole ``reference``; a curve also gets the film's pixel
    pitch, ``pitch_mm`` (:attr:`~pacam_render.exposure.plan.CapturePlan.pitch_mm`).

    Returns
    -------
    dict
        ``relative_illumination`` and, for a curve, ``pixel_pitch`` (mm).
    """
    ri = spec.relative_illumination
    if ri == "off" or mode(spec.mode).schedule is None:
        return {}
    if ri == "cos4":
        return {"relative_illumination": ri}
    return {"relative_illumination": ri, "pixel_pitch": pitch_mm}


LEAKY_SCHEDULES = ("static", "parabolic", "centres")
"""The sensor schedules that show discs on the LCoS, which ``lcos_contrast`` can leak."""


def contrast_params(spec: CaptureSpec, params: dict) -> dict:
    """``lcos_contrast`` for the sensor, where the mode shows discs on the LCoS; a note where
    it does not (Levin's moving camera, the fluttered shutter, the pinhole)."""
    if spec.lcos_contrast is None:
        return {}
    if params.get("schedule") in LEAKY_SCHEDULES:
        return {"lcos_contrast": float(spec.lcos_contrast)}
    note(
        f"lcos_contrast has no effect in {spec.mode} mode: it shows no disc on the LCoS "
        f"(schedule {params.get('schedule', 'none')})"
    )
    return {}


SWITCHING_SCHEDULES = ("parabolic", "centres", "bitmap", "flutter")
"""The sensor schedules that show a sequence of patterns on the LCoS, which switch between them;
a ``static`` opening (normal, short), Levin's moving camera and a continuous parabola switch
none."""


def switched_patterns(params: dict, cam: CameraDesign) -> int:
    """How many patterns the mode's schedule (``params``, the sensor's) switches between on the
    LCoS over the exposure: the design's ``n_patterns``, or 1 where it shows one opening or
    moves it continuously (the LCoS's switching then blends nothing)."""
    schedule = params.get("schedule")
    if schedule not in SWITCHING_SCHEDULES or params.get("continuous"):
        return 1
    if schedule == "flutter":  # the shutter's open and closed runs: its transitions + 1
        bits = flutter_code(params.get("flutter_code", RASKAR_2006_CODE))
        return 1 + int(np.count_nonzero(bits[1:] != bits[:-1]))
    return cam.n_patterns


def switching_params(spec: CaptureSpec, params: dict, cam: CameraDesign) -> dict:
    """``lcos_switching`` (ms) for the sensor where the mode switches discs on the LCoS
    (discrete parabolic or centres schedules), at most a pattern's time (checked here, before
    the plugin is built); a note where it does not switch."""
    t = spec.lcos_switching_ms
    if not t:
        return {}
    if params.get("schedule") in ("parabolic", "centres") and not params.get("continuous"):
        width = cam.exposure_ms / cam.n_patterns
        if t > width:
            raise ParameterError(
                f"lcos_switching_ms ({t:g} ms) must be at most a pattern's time: {width:g} ms "
                f"(the {cam.exposure_ms:g} ms exposure / {cam.n_patterns} patterns)"
            )
        return {"lcos_switching": float(t)}
    note(
        f"lcos_switching_ms has no effect in {spec.mode} mode: it switches no disc on the "
        f"LCoS (schedule {params.get('schedule', 'none')})"
    )
    return {}


def binned_pitch_mm(full: CameraDesign, width_px: int) -> float:
    """The pitch of a ``width_px`` wide sensor binned from ``full``'s pixels, mm: the design's
    pixel pitch times its full width over the capture's (a 320 px capture of the 1280 px sensor
    bins 4 x 4). The plan computes it once (:attr:`~.plan.CapturePlan.pitch_mm`)."""
    return full.pixel_pitch_mm * full.width_px / width_px


def illumination_map(spec: CaptureSpec, cam: CameraDesign, pitch_mm: float):
    """The capture's relative-illumination map, (h, w) float32 over its window, or None when
    ``off`` or for the ``reference``
    (:func:`~pacam_render.model.illumination.relative_illumination_map`)."""
    params = illumination_params(spec, pitch_mm)
    if not params:
        return None

    m = relative_illumination_map(
        params["relative_illumination"],
        spec.width,
        spec.height,
        cam.fov_deg,
        spec.crop,
        params.get("pixel_pitch"),
    )
    return m.astype("float32")


def illumination_record(spec: CaptureSpec, cam: CameraDesign, ri_map) -> dict | None:
    """The record's ``relative_illumination`` block: the setting, its law, the map's range,
    how readers flat-field, and (cos4) the exact thin-lens integral's departure from cos^4 at
    the window's farthest corner at this capture's F-number."""
    if ri_map is None:
        return None

    ri = spec.relative_illumination
    out = {
        "setting": ri,
        "law": "cos^4 of the chief ray's field angle (thin lens)"
        if ri == "cos4"
        else f"the curve in {ri}, linear between its points",
        "layer": "relative_illumination",
        "min": float(ri_map.min()),
        "max": float(ri_map.max()),
        "flat_field": "capture, noisy, subNN and mc_sigma are irradiance: readers divide them by "
        "the layer (read_capture, pacam deconvolve), which raises the noise towards the "
        "corners by 1 / map, as a camera's flat field does; sharp is the pinhole's radiance",
    }
    if ri == "cos4":
        t = film_tan_max(spec.width, spec.height, cam.fov_deg, spec.crop)
        exact = float(thin_lens_relative_illumination(t, cam.F_number)) * (1 + t * t) ** 2
        out["thin_lens_exact_over_cos4_at_corner"] = exact
        out["f_number"] = cam.F_number
    return out


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


def note_ignored_options(spec: CaptureSpec) -> None:
    """Options the mode does not use: say so rather than drop them silently."""
    if spec.relative_illumination != "off" and mode(spec.mode).schedule is None:
        note(
            f"relative_illumination has no effect in {spec.mode} mode: the pinhole reference "
            "is the ground truth, in radiance (captures in the other modes are flat-fielded "
            "against it)"
        )
    if spec.cover_px_per_ms is not None and mode(spec.mode).refocus:
        note(
            f"cover_px_per_ms has no effect in {spec.mode} mode: it focuses on the object, so the "
            "solved defocus is not used (it applies to coded, coded_continuous and levin)"
        )
    unused = _schedule_unused(spec.mode) if spec.schedule is not None else []
    if unused:  # recorded in the capture's notes; its camera leaves the openings out
        used = {"radius", "exposure"} - set(unused)
        note(
            f"`schedule`'s {_words(unused)} are not used in {spec.mode} mode ("
            f"{MODES[spec.mode].summary}): "
            + (f"only its {_words(sorted(used))} are" if used else "it has no effect")
        )


def note_binning(spec: CaptureSpec, cam: CameraDesign, full: CameraDesign | None = None) -> None:
    """A coded capture whose blur is sub-pixel is a binned camera: say so, and what to do
    (``full``: the design as read, at its full size; None reads it)."""
    full = full_design(spec) if full is None else full
    if not mode(spec.mode).needs_parallax or cam.r_px >= 1.0:
        return
    binned = full.width_px / spec.width
    fig = cam.summary()  # a designed schedule's figures are fitted to its own openings
    if fig["a_i_px_per_ms2"] is None:
        return
    note(
        f"at {spec.width}x{spec.height} px the sensor is the preset's {full.width_px}x"
        f"{full.height_px} binned {binned:.3g}x: the coded blur is sub-pixel (r = "
        f"{cam.r_px:.3g} px, a_i = {fig['a_i_px_per_ms2']:.3g} px/ms^2, invariant |s| <= "
        f"{fig['velocity_range_px_per_ms']:.3g} px/ms at this size); to see the camera at its real "
        f"pixel scale, render a window of the full sensor with `crop` X,Y,W,H"
    )
