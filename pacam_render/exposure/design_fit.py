"""Whether each object of a capture lies inside what its camera was designed for.

A coded design fits one depth and a range of speeds: a surface at depth Z is blurred by a
pillbox of radius r(Z) = |beta(Z)| R (Eqs. 9, 12), and the blur is the same for every speed
|s| <= |a_i(Z)| T (Eq. 18). The analytic PSF a user deconvolves with is the design's (r at the
design depth, s = 0), so an object far from that depth, or faster than the range, is restored
with a kernel that does not fit it. The ground-truth layers know both (``depth``, ``velocity``
and ``object_id``); this module summarises them per object and says which objects are off.
"""

from __future__ import annotations

import numpy as np

from ..model import optics
from ..model.camera import CameraDesign
from ..model.modes import mode as mode_of

DEPTH_TOLERANCE = (0.5, 0.2)
"""An object is off the design depth when its defocus radius differs from the design's by more
than 0.5 px and by more than 20 % of it: below that the s = 0 kernel still fits (pixel scale)."""
SPEED_QUANTILE = 95.0
"""An object's speed is the 95th percentile of |velocity| over its pixels (a few edge pixels
of another shape's motion do not count)."""


def object_fit(layers: dict, objects: dict, cam: CameraDesign, mode: str) -> dict:
    """Each object's median depth, defocus radius and speed, against the capture's design.

    Parameters
    ----------
    layers : dict
        The truth layers ``depth`` (H, W) mm, ``object_id`` (H, W) and ``velocity`` (H, W, 2)
        px/ms (:mod:`.truth`).
    objects : dict
        Object id (str) to shape id (the record's ``objects``).
    cam : CameraDesign
        The mode's camera (its focus and opening; for ``levin`` the coded design it keeps).
    mode : str
        The capture mode: its lens focus (the mode table) sets the defocus; a parabolic
        aperture's range scales with depth like beta (Eq. 18), Levin's body motion's does not,
        and other modes have none (nor does a designed schedule: its cover is its own).

    Returns
    -------
    dict
        Shape id to ``depth_mm``, ``r_px`` (its defocus radius), ``speed_px_per_ms`` and, where
        it applies, ``range_px_per_ms``, with ``off_depth`` and ``too_fast`` flags.
    """
    ids, depth, vel = layers["object_id"], layers["depth"], layers["velocity"]
    speed = np.hypot(vel[..., 0], vel[..., 1])
    m = mode_of(mode)
    lens = cam.with_(focus_distance_mm=cam.object_depth_mm) if m.lens_on_object else cam
    out = {}
    for key, name in objects.items():
        mask = (ids == int(key)) & (depth > 0)
        if not mask.any():
            continue
        z = float(np.median(depth[mask]))
        entry = {
            "depth_mm": z,
            "r_px": _radius_px(lens, z),
            "speed_px_per_ms": float(np.percentile(speed[mask], SPEED_QUANTILE)),
        }
        off = abs(entry["r_px"] - lens.r_px)
        entry["off_depth"] = bool(off > DEPTH_TOLERANCE[0] and off > DEPTH_TOLERANCE[1] * lens.r_px)
        if m.schedule in ("parabolic", "camera_parabolic") and not cam.designed:
            scale = _beta(cam, z) / cam.beta_px_per_mm if m.schedule == "parabolic" else 1.0
            entry["range_px_per_ms"] = float(abs(scale) * cam.velocity_range_px_per_ms)
            entry["too_fast"] = bool(entry["speed_px_per_ms"] > entry["range_px_per_ms"])
        out[name] = entry
    return out


def fit_notes(fit: dict, cam: CameraDesign, mode: str) -> list[str]:
    """One line per object outside the design (:func:`object_fit`), or none."""
    if mode_of(mode).lens_on_object:
        cam = cam.with_(focus_distance_mm=cam.object_depth_mm)
    notes = []
    for name, e in fit.items():
        if e["off_depth"]:
            notes.append(
                f"object {name!r} lies at {e['depth_mm']:.0f} mm (median), where its defocus "
                f"radius is {e['r_px']:.2f} px against the design's r = {cam.r_px:.2f} px at "
                f"{cam.object_depth_mm:.0f} mm: the {mode} PSF of the design does not fit it"
            )
        if e.get("too_fast"):
            notes.append(
                f"object {name!r} moves at {e['speed_px_per_ms']:.2f} px/ms, outside the "
                f"motion-invariant range |s| <= {e['range_px_per_ms']:.2f} px/ms at its depth: "
                "its blur is not the s = 0 PSF"
            )
    return notes


def _beta(cam: CameraDesign, z_mm: float) -> float:
    return optics.beta_px_per_mm(z_mm, cam.focus_distance_mm, cam.fov_deg, cam.width_px)


def _radius_px(cam: CameraDesign, z_mm: float) -> float:
    return optics.defocus_radius_px(_beta(cam, z_mm), cam.R_mm)
