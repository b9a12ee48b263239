"""Projection and motion: the camera pose every scene assumes, pinhole projection and rigid
motion of shapes (:class:`Motion`); :class:`~.description.SceneAnimator` moves the shapes of a
loaded scene with them.

Geometry conventions
--------------------
* Millimetres and milliseconds. The camera sits at the origin looking down +z: Mitsuba's
  ``look_at(origin=(0, 0, 0), target=(0, 0, 1), up=(0, 1, 0))``, which is the identity
  (:func:`default_camera_to_world`). An object at depth Z has z = Z.
* World +y shows at the top of the image and world **+x on the image's left** (checked with a
  render; the tests keep checking it): image column u grows along -x, row v along -y. A pinhole
  with focal length f_px maps (x, y, z) to u = W/2 - f_px x/z, v = H/2 - f_px y/z
  (:func:`project_px`). "Moving right" in the image is a velocity along -x.
* Time t runs over the exposure [-T, T], t = 0 at mid-exposure (PHYSICS.md). The scene's
  geometry is the pose at t = 0; motion moves shapes relative to it.

A :class:`Motion` is a velocity in mm/ms, optionally with keyframed transforms about a pivot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import ParameterError, check_finite, check_positive, did_you_mean
from ..model.camera import CameraDesign
from ..render.backend import select_variant


def _mi():
    """Mitsuba with a variant active (the package's choice if none is set yet)."""
    import mitsuba as mi

    if mi.variant() is None:
        select_variant()
    return mi


def default_camera_to_world():
    """The sensor pose every scene assumes: at the origin, looking down +z, +y up."""
    mi = _mi()
    return mi.ScalarTransform4f().look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])


def project_px(points_mm, camera: CameraDesign) -> np.ndarray:
    """Pinhole image position (column u, row v) in px of points (..., 3) in mm, measured from
    the film's top-left corner (pixel centres at k + 0.5), for the default camera pose."""
    p = np.asarray(points_mm, float)
    f = camera.focal_length_px
    u = 0.5 * camera.width_px - f * p[..., 0] / p[..., 2]
    v = 0.5 * camera.height_px - f * p[..., 1] / p[..., 2]
    return np.stack([u, v], -1)


def image_to_scene_velocity(velocity_px_per_ms, depth_mm: float, camera: CameraDesign):
    """Scene velocity (mm/ms, 3-vector) of a fronto-parallel motion at ``depth_mm`` that moves
    ``velocity_px_per_ms`` = (du, dv) (or du alone) in ``camera``'s image: |alpha| = f_px / Z
    px per mm, with image right = -x and image down = -y."""
    Z = check_positive("depth_mm", depth_mm, "mm")
    v = np.asarray(velocity_px_per_ms, float)
    v = np.array([float(v), 0.0]) if v.ndim == 0 else v
    if v.shape != (2,) or not np.all(np.isfinite(v)):
        raise ParameterError(f"velocity_px_per_ms must be finite du or (du, dv), got {v!r}")
    du, dv = v
    k = Z / camera.focal_length_px  # mm per px at depth Z
    return np.array([-du * k, -dv * k, 0.0]) + 0.0  # + 0.0: no negative zeros


def _translate(v) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = v
    return m


@dataclass(frozen=True)
class Motion:
    """Rigid motion of one shape relative to its pose at t = 0 (mm, ms).

    M(t) = Translate(v t) . Translate(p) . K(t) . Translate(-p), where ``velocity_mm_per_ms``
    is v, ``pivot_mm`` is p and K(t) interpolates ``keyframes`` ((t_ms, 4x4 matrix) pairs,
    increasing t; rotation by slerp, the rest linearly). Keyframes cover a limited time range:
    asking outside it is an error, not an extrapolation.
    """

    velocity_mm_per_ms: tuple[float, float, float] = (0.0, 0.0, 0.0)
    keyframes: tuple[tuple[float, tuple[tuple[float, ...], ...]], ...] = ()
    pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        v = tuple(check_finite("velocity_mm_per_ms", x) for x in self.velocity_mm_per_ms)
        p = tuple(check_finite("pivot_mm", x) for x in self.pivot_mm)
        if len(v) != 3 or len(p) != 3:
            raise ParameterError("velocity_mm_per_ms and pivot_mm must have 3 components (mm)")
        object.__setattr__(self, "velocity_mm_per_ms", v)
        object.__setattr__(self, "pivot_mm", p)
        kf = tuple((float(t), tuple(map(tuple, np.asarray(m, float)))) for t, m in self.keyframes)
        object.__setattr__(self, "keyframes", kf)
        self._check_keyframes()

    def _check_keyframes(self) -> None:
        if not self.keyframes:
            return
        t = np.array([k[0] for k in self.keyframes])
        m = np.array([k[1] for k in self.keyframes])
        if len(t) < 2 or not np.all(np.diff(t) > 0) or not np.all(np.isfinite(t)):
            raise ParameterError("keyframes need >= 2 finite, strictly increasing t_ms")
        if m.shape[1:] != (4, 4) or not np.all(np.isfinite(m)):
            raise ParameterError("each keyframe matrix must be a finite 4x4 matrix")
        if not np.allclose(m[:, 3], [0, 0, 0, 1]) or np.any(np.linalg.det(m[:, :3, :3]) <= 0):
            raise ParameterError("keyframe matrices must be affine with a positive determinant")

    @property
    def is_static(self) -> bool:
        if any(self.velocity_mm_per_ms):
            return False
        return all(np.allclose(k[1], np.eye(4)) for k in self.keyframes)  # K(t) = I throughout

    @property
    def time_range_ms(self) -> tuple[float, float]:
        """Times at which the motion is defined."""
        if not self.keyframes:
            return (-math.inf, math.inf)
        return (self.keyframes[0][0], self.keyframes[-1][0])

    @cached_property
    def _interp(self):
        from scipy.spatial.transform import Rotation, Slerp

        t = np.array([k[0] for k in self.keyframes])
        m = np.array([k[1] for k in self.keyframes])
        u, _, vt = np.linalg.svd(m[:, :3, :3])
        rot = u @ vt  # polar decomposition A = R S
        stretch = np.transpose(rot, (0, 2, 1)) @ m[:, :3, :3]
        return t, Slerp(t, Rotation.from_matrix(rot)), stretch, m[:, :3, 3]

    def _keyframe_matrix(self, t_ms: float) -> np.ndarray:
        times, slerp, stretch, trans = self._interp
        i = int(np.clip(np.searchsorted(times, t_ms) - 1, 0, len(times) - 2))
        w = (t_ms - times[i]) / (times[i + 1] - times[i])
        k = np.eye(4)
        k[:3, :3] = slerp([t_ms]).as_matrix()[0] @ ((1 - w) * stretch[i] + w * stretch[i + 1])
        k[:3, 3] = (1 - w) * trans[i] + w * trans[i + 1]
        return k

    def matrix_at(self, t_ms: float) -> np.ndarray:
        """World-space 4x4 transform from the t = 0 pose to the pose at ``t_ms``."""
        t = check_finite("t_ms", t_ms)
        m = _translate(np.multiply(self.velocity_mm_per_ms, t))
        if self.keyframes:
            lo, hi = self.time_range_ms
            if not lo <= t <= hi:
                raise ParameterError(
                    f"t_ms must be in [{lo:g}, {hi:g}] ms (the keyframed range), got {t_ms!r}"
                )
            p = np.asarray(self.pivot_mm)
            m = m @ _translate(p) @ self._keyframe_matrix(t) @ _translate(-p)
        return m

    def apply(self, points_mm, t_ms: float) -> np.ndarray:
        """Points (N, 3) of the t = 0 pose moved to ``t_ms``."""
        m = self.matrix_at(t_ms)
        return np.asarray(points_mm, float) @ m[:3, :3].T + m[:3, 3]

    def to_json(self) -> dict:
        out: dict[str, Any] = {"velocity_mm_per_ms": list(self.velocity_mm_per_ms)}
        if self.keyframes:
            out["pivot_mm"] = list(self.pivot_mm)
            out["keyframes"] = [
                {"t_ms": t, "matrix": [list(r) for r in m]} for t, m in self.keyframes
            ]
        return out

    @classmethod
    def from_json(cls, d: dict, what: str = "motion description") -> Motion:
        """The motion of a JSON entry, checking its keys: a misspelt key would otherwise leave
        the shape still (``what`` names the entry in messages)."""
        check_keys(what, d, MOTION_KEYS)
        try:
            kf = []
            for k, frame in enumerate(d.get("keyframes", ())):
                check_keys(f"{what}, keyframe {k}", frame, KEYFRAME_KEYS, KEYFRAME_KEYS)
                kf.append((frame["t_ms"], frame["matrix"]))
            return cls(
                tuple(d.get("velocity_mm_per_ms", (0, 0, 0))),
                tuple(kf),
                tuple(d.get("pivot_mm", (0, 0, 0))),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, ParameterError):
                raise
            raise ParameterError(f"{what} is not valid ({exc}): {d!r}") from exc


MOTION_KEYS = ("velocity_mm_per_ms", "pivot_mm", "keyframes")
"""The keys of one shape's motion in a ``<stem>.motion.json`` (all optional)."""
KEYFRAME_KEYS = ("t_ms", "matrix")
"""The keys of one keyframe (both required)."""


def check_keys(what: str, d: Any, valid: tuple[str, ...], required: tuple[str, ...] = ()) -> None:
    """Refuse a JSON object with a key outside ``valid`` or without one of ``required``.

    Parameters
    ----------
    what : str
        The object's name in messages, e.g. ``"motion file 'a.motion.json', shape 'ball'"``.
    d : Any
        The parsed JSON value.
    valid, required : tuple of str
        The keys allowed, and those that must be present.

    Raises
    ------
    ParameterError
        Naming the key at fault (and the nearest valid one) and listing the valid keys.
    """
    listed = f"valid keys: {', '.join(valid)}"
    if not isinstance(d, dict):
        raise ParameterError(f"{what} must be a JSON object ({listed}), got {d!r}")
    for key in d:
        if key not in valid:
            hint = did_you_mean(key, valid, cutoff=0.4)
            raise ParameterError(f"{what} has an unknown key {key!r}{hint}; {listed}")
    missing = [k for k in required if k not in d]
    if missing:
        raise ParameterError(f"{what} lacks the key {missing[0]!r}; {listed}")


def _bbox_corners(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    return np.where(idx == 1, hi, lo)


def look_at(origin, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Mitsuba's look_at as a numpy 4x4: local +z towards ``target``."""
    o, t, u = (np.asarray(x, float) for x in (origin, target, up))
    d = (t - o) / np.linalg.norm(t - o)
    left = np.cross(u, d)
    left /= np.linalg.norm(left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, np.cross(d, left), d, o
    return m
