"""The capture modes: one table that says what each mode *is*.

A mode fixes how a camera built from one coded design takes its picture: the aperture schedule
the sensor shows, where the lens focuses, how wide it opens, how long it exposes, and which
analytic PSF describes the result. Captures (:mod:`pacam_render.exposure.direct`), rendered
PSFs (:mod:`pacam_render.psf_render.render`), the analytic PSFs
(:func:`pacam_render.psf.analytic.design_psf`), deconvolution, ``pacam reproduce`` and the
demo all read this table, so the ray-traced capture and its analytic kernel cannot drift apart.

================== =========== ======== ========= ========== ==============================
mode               schedule    focus    opening   exposure   analytic PSF
================== =========== ======== ========= ========== ==============================
normal             static      object   R         2T         box |s| 2T (Sec. 3.3)
coded              parabolic   design   R         2T         16 held patterns (exact)
coded_continuous   parabolic*  design   R         2T         Phi, Eq. 14
short              static      object   R_max     0.679 ms   box |s| 0.679 ms (Fig. 8)
levin              camera body object   R         2T         phi, Eq. 1 (Levin et al. 2008)
flutter            52 chops    object   R         2T         Raskar et al. 2006
reference          pinhole     -        -         -          none (the sharp t = 0 image)
================== =========== ======== ========= ========== ==============================

(*) evaluated at each ray's time, the N -> infinity limit of the 16 patterns.

``normal``, ``levin`` and ``flutter`` keep the coded design's opening R, so every 45 ms mode
collects comparable light. ``levin`` keeps the coded design itself (its a_i follows the
design's focus through Eq. 18) but the lens focuses on the object, as Levin's camera does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from . import paper
from .camera import CameraDesign


@dataclass(frozen=True)
class Mode:
    """One capture mode (see the module's table).

    Attributes
    ----------
    name : str
    schedule : str or None
        The ``programmable_aperture`` schedule; None for the pinhole reference.
    refocus : bool
        A capture refocuses the design on the object (r = 0) before shooting.
    lens_on_object : bool
        The sensor's lens focuses on the object even though the design is kept (``levin``).
    full_opening : bool
        A capture opens the whole lens, R = R_max (F_min).
    exposure_ms : float or None
        The mode's own exposure; None: the design's 2T.
    psf : str or None
        The analytic kernel: a key of
        :data:`pacam_render.psf.analytic.MODE_TRAJECTORIES`, the point's image path.
    continuous : bool
        The parabola is evaluated at each ray's time instead of per pattern.
    moves_image : bool
        The image of a still point moves during the exposure: its t = 0 image is displaced
        from the pinhole image by -a_i T^2 / 4 (the aperture, or Levin's body, starts at an
        edge).
    summary : str
    """

    name: str
    schedule: str | None
    refocus: bool
    lens_on_object: bool
    full_opening: bool
    exposure_ms: float | None
    psf: str | None
    continuous: bool = False
    moves_image: bool = False
    summary: str = ""

    @property
    def needs_parallax(self) -> bool:
        """The aperture itself moves: the design must see parallax (beta != 0, Eq. 9)."""
        return self.schedule == "parabolic"


MODES: dict[str, Mode] = {
    m.name: m
    for m in (
        Mode("normal", "static", True, False, False, None, "static",
             summary="a normal camera: still opening R, focused on the object"),
        Mode("coded", "parabolic", False, False, False, None, "discrete_coded",
             moves_image=True,
             summary="the programmable aperture: 16 held openings along a parabola"),
        Mode("coded_continuous", "parabolic", False, False, False, None, "coded",
             continuous=True, moves_image=True,
             summary="the continuous parabola of Eq. 14 (the paper's model)"),
        Mode("short", "static", True, False, True, paper.SHORT_EXPOSURE_MS, "short",
             summary=f"a short exposure: {paper.SHORT_EXPOSURE_MS} ms, full opening (F_min)"),
        Mode("levin", "camera_parabolic", False, True, False, None, "levin",
             continuous=True, moves_image=True,
             summary="Levin et al. 2008: the camera body moves on a parabola, lens in focus"),
        Mode("flutter", "flutter", True, False, False, None, "flutter",
             summary="Raskar et al. 2006: a fluttered shutter, 52 chops"),
        Mode("reference", None, True, False, False, None, None,
             summary="a pinhole at t = 0: the sharp ground truth"),
    )
}  # fmt: skip
"""Every capture mode, by name."""

MODES_WITH_PSF = tuple(name for name, m in MODES.items() if m.psf is not None)
"""The modes that have an analytic PSF (and can be rendered as a PSF)."""


def mode(name: str) -> Mode:
    """The :class:`Mode` called ``name``, or :class:`ParameterError` listing the valid ones.

    Examples
    --------
    >>> m = mode("short")
    >>> m.exposure_ms, m.full_opening, m.refocus
    (0.679, True, True)
    >>> mode("blurry")
    Traceback (most recent call last):
    ...
    pacam_render.errors.ParameterError: unknown mode 'blurry'; valid: normal, coded, ...
    """
    if name not in MODES:
        raise ParameterError(f"unknown mode {name!r}; valid: {', '.join(MODES)}")
    return MODES[name]


DESIGNED_REFUSED = {"coded_continuous": "continuous limit", "levin": "camera-motion equivalent"}
"""Modes that a designed schedule cannot take, and what it lacks for them."""


def mode_exposure_ms(design: CameraDesign, name: str) -> float:
    """The exposure a mode takes with ``design``, ms."""
    m = mode(name)
    return design.exposure_ms if m.exposure_ms is None else m.exposure_ms


def capture_camera(design: CameraDesign, name: str) -> CameraDesign:
    """The camera that takes a ``name`` capture, derived from the coded ``design``.

    Its focus, opening and exposure follow the mode (see the table); its analytic PSF is
    ``design_psf(capture_camera(design, name), name)``.
    """
    m = mode(name)
    if design.designed and name in DESIGNED_REFUSED:
        raise ParameterError(
            f"mode {name!r} follows the parabola of Eq. 11; a designed schedule "
            f"(pattern_centres_mm) has no {DESIGNED_REFUSED[name]}: use mode 'coded'"
        )
    cam = design.with_(focus_distance_mm=design.object_depth_mm) if m.refocus else design
    if m.full_opening:
        cam = cam.with_(R_mm=design.R_max_mm)
    if m.exposure_ms is not None:
        cam = cam.with_(exposure_ms=m.exposure_ms)
    return cam


def sensor_params(cam: CameraDesign, name: str) -> dict:
    """The ``programmable_aperture`` parameters that show mode ``name`` with camera ``cam``.

    Empty for the reference, which is Mitsuba's pinhole ``perspective`` sensor. A coded mode
    at the full opening (R = R_max) cannot move its aperture and shows the static disc.
    """
    m = mode(name)
    if m.schedule is None:
        return {}
    focus = cam.object_depth_mm if m.lens_on_object else cam.focus_distance_mm
    p = {"lens_radius": cam.R_max_mm, "aperture_radius": cam.R_mm, "focus_distance": focus}
    if m.schedule == "parabolic":
        cam.require_parallax()
        if cam.pattern_masks is not None and not m.continuous:
            masks = cam.pattern_masks
            return {**p, "schedule": "bitmap", "masks": masks.array, "mask_pitch": masks.pitch_mm}
        if cam.designed and not m.continuous:
            return {**p, "schedule": "centres", "centres": _local_centres(cam)}
        if cam.R_mm >= cam.R_max_mm:  # F_min: the full opening cannot move
            return {**p, "schedule": "static"}
        extra = {"continuous": True} if m.continuous else {}
        return {**p, "schedule": "parabolic", "n_patterns": cam.n_patterns, **extra}
    if m.schedule == "camera_parabolic":
        return {**p, "schedule": "camera_parabolic", "image_acceleration": cam.a_i_px_per_ms2}
    return {**p, "schedule": m.schedule}


def local_centres_mm(cam: CameraDesign) -> np.ndarray:
    """The openings' centres in the plugin's local frame (mm, (n, 2)): local +x is the image's
    left and +y its top, so (x right, y down) maps to (-x, -y)."""
    return -cam.pattern_centres_xy_mm()


def _local_centres(cam: CameraDesign) -> str:
    """:func:`local_centres_mm` as the plugin's ``"x y; ..."`` string, exact (repr)."""
    return "; ".join(f"{x!r} {y!r}" for x, y in local_centres_mm(cam).tolist())


def pattern_offsets_px(cam: CameraDesign) -> np.ndarray:
    """Where each pattern images a still point, px from its pinhole image, (n, 2) as (u, v):
    beta_px times the opening's centre (Eq. 8), for the designed schedule or the parabola."""
    return cam.beta_px_per_mm * cam.pattern_centres_xy_mm()


def held_offsets_px(cam: CameraDesign) -> np.ndarray:
    """:func:`pattern_offsets_px` with u measured from the pattern shown at t = 0 (pattern
    n // 2, :func:`~pacam_render.model.schedule.pattern_index`): the kernel's ``t0`` origin."""
    off = pattern_offsets_px(cam)
    off[:, 0] -= off[cam.n_patterns // 2, 0]
    return off


def image_acceleration(cam: CameraDesign, name: str) -> float:
    """The image acceleration a_i of mode ``name`` (Eq. 18), px/ms^2; 0 if nothing moves."""
    return cam.a_i_px_per_ms2 if mode(name).moves_image else 0.0


def t0_offset_px(cam: CameraDesign, name: str) -> float:
    """Where a still point images at t = 0, px from its pinhole image: -a_i T^2 / 4.

    The aperture (or Levin's body) starts at an edge: X_a(0) = -(R_max - R), so the coded
    image sits at -beta (R_max - R) = -a_i T^2 / 4 (Eqs. 10, 17). 0 for still modes.
    """
    if cam.designed and mode(name).moves_image:
        # the pattern shown at t = 0 (schedule.pattern_index: t = 0 opens pattern n // 2)
        return float(pattern_offsets_px(cam)[cam.n_patterns // 2, 0])
    T = 0.5 * mode_exposure_ms(cam, name)
    return -0.25 * image_acceleration(cam, name) * T * T
