"""Edits of a scene description for sweeps: scale how fast its shapes move, or move the moving
shapes to another depth. Both return a new description and leave the original as it was."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import ParameterError, check_positive
from ..model.camera import CameraDesign
from .description import SceneDescription, fastest_image_speed_px_per_ms
from .motion import Motion

SPEED_WINDOW_MS = (-0.5, 0.5)
"""Where a scene's speed is measured: about t = 0, ms."""


def scaled_motion(motion: Motion, k: float) -> Motion:
    """``motion`` run ``k`` times as fast: M_k(t) = M(k t) (velocity x k, keyframe times / k)."""
    check_positive("speed scale", k)
    keyframes = tuple((t / k, m) for t, m in motion.keyframes)
    v = tuple(k * x for x in motion.velocity_mm_per_ms)
    return Motion(v, keyframes, motion.pivot_mm)


def shape_speed_px_per_ms(desc: SceneDescription, sid: str, camera: CameraDesign) -> float:
    """Image speed of shape ``sid`` at t = 0, px/ms of ``camera``.

    A translation of a shape of known depth Z moves f_px |(v_x, v_y)| / Z (the speed the
    built-in scenes are specified by, on their reference surface); otherwise the fastest
    corner of its bounding box about t = 0
    (:func:`~pacam_render.scenes.description.fastest_image_speed_px_per_ms`).
    """
    m, z = desc.motions[sid], desc.depths_mm.get(sid)
    if m.is_static:
        return 0.0
    if z and not m.keyframes:
        return camera.focal_length_px * float(np.hypot(*m.velocity_mm_per_ms[:2])) / z
    return fastest_image_speed_px_per_ms(_only(desc, sid), camera, SPEED_WINDOW_MS)


def scene_speed_px_per_ms(desc: SceneDescription, camera: CameraDesign) -> float:
    """The fastest moving shape's image speed at t = 0, px/ms of ``camera``; 0 if static."""
    return max((shape_speed_px_per_ms(desc, s, camera) for s in desc.moving_ids), default=0.0)


def with_speed(desc: SceneDescription, speed_px_per_ms: float, camera: CameraDesign):
    """``desc`` with every motion scaled so that its fastest shape moves ``speed_px_per_ms``.

    Raises
    ------
    ParameterError
        If nothing in the scene moves (there is no speed to scale).
    """
    base = scene_speed_px_per_ms(desc, camera)
    if base <= 0:
        raise ParameterError(f"speed_px_per_ms: nothing moves in scene {desc.name!r}")
    k = check_positive("speed_px_per_ms", speed_px_per_ms, "px/ms") / base
    motions = {sid: scaled_motion(m, k) for sid, m in desc.motions.items()}
    return replace(desc, motions=motions)


def moving_depth_mm(desc: SceneDescription, camera: CameraDesign) -> float | None:
    """Depth of the fastest moving shape (its ``depths_mm`` entry), mm; None if not known."""
    speeds = {sid: shape_speed_px_per_ms(desc, sid, camera) for sid in desc.moving_ids}
    if not speeds:
        return None
    return desc.depths_mm.get(max(speeds, key=speeds.get))


def _only(desc: SceneDescription, sid: str) -> SceneDescription:
    return replace(desc, motions={sid: desc.motions[sid]})


def at_depth(desc: SceneDescription, depth_mm: float, camera: CameraDesign):
    """``desc`` with its moving shapes moved along z so that the fastest is at ``depth_mm``.

    Every moving shape moves by the same dz (its pivot too), and its velocity is scaled by
    (Z + dz) / Z, so that the image speed of its translation stays as it was: depth and speed
    are separate axes of a sweep.

    Raises
    ------
    ParameterError
        If the scene's shapes are loaded objects (a scene file), or a depth is unknown.
    """
    z0 = moving_depth_mm(desc, camera)
    if z0 is None:
        raise ParameterError(f"depth_mm: scene {desc.name!r} has no moving shape of known depth")
    dz = check_positive("depth_mm", depth_mm, "mm") - z0
    out = replace(
        desc,
        scene_dict=dict(desc.scene_dict),
        motions=dict(desc.motions),
        bboxes_mm=dict(desc.bboxes_mm),
        depths_mm=dict(desc.depths_mm),
    )
    for sid in desc.moving_ids:
        entry, z = desc.scene_dict[sid], desc.depths_mm.get(sid)
        if not isinstance(entry, dict) or z is None or z + dz <= 0:
            raise ParameterError(
                f"depth_mm: shape {sid!r} cannot be moved (a built-in scene's shape of known "
                f"depth is needed, in front of the camera)"
            )
        shift = np.eye(4)
        shift[2, 3] = dz
        out.scene_dict[sid] = {**entry, "to_world": shift @ entry.get("to_world", np.eye(4))}
        lo, hi = desc.bboxes_mm[sid]
        out.bboxes_mm[sid] = (lo + [0, 0, dz], hi + [0, 0, dz])
        out.depths_mm[sid] = z + dz
        m = desc.motions[sid]
        v = tuple((z + dz) / z * x for x in m.velocity_mm_per_ms)
        out.motions[sid] = Motion(v, m.keyframes, tuple(np.add(m.pivot_mm, (0, 0, dz))))
    return out
