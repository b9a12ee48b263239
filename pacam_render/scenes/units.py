"""Scene units: pacam scenes are in millimetres, where Mitsuba's examples are in metres.

A scene in metres renders as near-black noise with no error: its surfaces sit a few mm from a
lens designed for objects hundreds of mm away. Before a capture renders, :func:`check_units`
measures how near the camera's view meets a surface and how large the scene is, against the
design's object depth, and notes a scene that looks like metres.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..limits import PacamWarning
from ..model.camera import CameraDesign
from .motion import _mi

NEAR_FRACTION = 0.05
"""A visible surface nearer than this fraction of the design's object depth (25 mm for the
prototype's 500 mm) is noted: nothing so near the lens can be the subject."""
SMALL_FRACTION = 0.05
"""A whole scene smaller than this fraction of the object depth across ..."""
SMALL_NEAR_FRACTION = 0.2
"""... and nearer than this fraction of it is noted too: a metres scene a few tens of metres
away (a few tens of mm here) is a speck near the lens."""


def nearest_surface_mm(scene, camera: CameraDesign, n: int = 48) -> float:
    """Distance (mm) from the camera to the nearest surface that a grid of ``n`` pinhole rays
    across (and as many down as the aspect ratio gives) meets over the camera's whole view;
    inf when none meets one. ``scene`` is a loaded ``mi.Scene`` in the default camera pose."""
    mi = _mi()
    w, h, f = camera.width_px, camera.height_px, camera.focal_length_px
    m = max(2, round(n * h / w))
    u, v = np.meshgrid((np.arange(n) + 0.5) * w / n, (np.arange(m) + 0.5) * h / m)
    d = np.stack([(0.5 * w - u) / f, (0.5 * h - v) / f, np.ones_like(u)], -1).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if mi.variant().startswith("scalar"):
        ts = [scene.ray_intersect_preliminary(mi.Ray3f([0, 0, 0], list(x))).t for x in d]
        t = np.array(ts, float)
    else:
        ray = mi.Ray3f(mi.Point3f(0, 0, 0), mi.Vector3f(*(mi.Float(c) for c in d.T)))
        t = np.array(scene.ray_intersect_preliminary(ray).t, float)
    t = t[np.isfinite(t)]
    return float(t.min()) if t.size else math.inf


def scene_extent_mm(scene) -> tuple[float, float]:
    """(largest side of the box around all shapes, distance from the camera to the nearest
    shape's box), mm; (0, inf) for a scene without shapes."""
    boxes = [
        (np.array(s.bbox().min, float).ravel(), np.array(s.bbox().max, float).ravel())
        for s in scene.shapes()
    ]
    if not boxes:
        return 0.0, math.inf
    lo, hi = np.min([b[0] for b in boxes], 0), np.max([b[1] for b in boxes], 0)
    near = min(float(np.linalg.norm(np.clip(0.0, a, b))) for a, b in boxes)
    return float(np.max(hi - lo)), near


def units_note(scene, camera: CameraDesign) -> str | None:
    """The note for a scene that looks like metres (see :func:`check_units`), or None."""
    extent, box_near = scene_extent_mm(scene)
    near = nearest_surface_mm(scene, camera)
    if not math.isfinite(near):  # nothing in view: the nearest shape's box stands in
        near = box_near
    z = camera.object_depth_mm
    small = extent < SMALL_FRACTION * z and near < SMALL_NEAR_FRACTION * z
    if not (near < NEAR_FRACTION * z or small):
        return None
    return (
        f"the nearest surface is {near:.3g} mm from the camera and the whole scene is "
        f"{extent:.3g} mm across, for a camera designed for objects at {z:.4g} mm: is the "
        "scene in metres? pacam scenes are in mm (scale each shape's to_world by 1000)"
    )


def check_units(scene, camera: CameraDesign) -> None:
    """Note (a :class:`~pacam_render.limits.PacamWarning`) a scene that looks like metres.

    Parameters
    ----------
    scene : mitsuba.Scene
        The loaded scene, in the default camera pose (camera at the origin, looking down +z).
    camera : CameraDesign
        The capture's design: its view, and ``object_depth_mm`` as the scale the scene should
        have.

    Warns
    -----
    PacamWarning
        When the nearest surface in view is nearer than ``NEAR_FRACTION`` of the object depth,
        or the whole scene is smaller than ``SMALL_FRACTION`` of it and nearer than
        ``SMALL_NEAR_FRACTION`` of it.
    """
    note = units_note(scene, camera)
    if note is not None:
        warnings.warn(note, PacamWarning, stacklevel=2)
