"""Scenes and their motion: the built-in train set, soccer ball and walker, a PSF generator,
and Mitsuba scene files.

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

A :class:`SceneDescription` holds a Mitsuba scene dict *without a sensor* (the capture code adds
the camera), a suggested integrator, and a :class:`Motion` per moving shape (a velocity in
mm/ms, optionally with keyframed transforms about a pivot). :class:`SceneAnimator` moves the
shapes of a loaded scene to time t with ``mi.traverse`` / ``params.update()``. Load with
:meth:`SceneDescription.load`: it turns Mitsuba's mesh merging off, which would otherwise merge
meshes that share a material and lose the shape ids that motion refers to.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model.camera import CameraDesign, prototype
from . import assets as sa

SCENE_DIR = Path(__file__).resolve().parents[2] / "scenes"
"""The repository's ``scenes/`` folder: XML files exported from the built-in scenes."""

WHITE_IRRADIANCE = 0.8 * math.pi  # lights give a white diffuse surface a radiance of ~0.8
SOCCER_SPEED_PX_PER_MS = 1.0  # in the prototype's image: 0.66 m/s at 1000 mm, a hand-moved ball
WALKER_SPEED_MM_PER_MS = 1.4  # 1.4 m/s, a typical walking speed: 0.70 px/ms at 3000 mm


# ============================================================================================
# Mitsuba access, projection, camera
# ============================================================================================
def _mi():
    """Mitsuba with a variant active (the package's choice if none is set yet)."""
    import mitsuba as mi

    if mi.variant() is None:
        from ..render.backend import select_variant

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


# ============================================================================================
# Motion
# ============================================================================================
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
    def from_json(cls, d: dict) -> Motion:
        try:
            kf = tuple((k["t_ms"], k["matrix"]) for k in d.get("keyframes", ()))
            return cls(
                tuple(d.get("velocity_mm_per_ms", (0, 0, 0))),
                kf,
                tuple(d.get("pivot_mm", (0, 0, 0))),
            )
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, ParameterError):
                raise
            raise ParameterError(f"invalid motion description {d!r}: {exc}") from exc


# ============================================================================================
# Scene description
# ============================================================================================
@dataclass
class SceneDescription:
    """A scene without a sensor, and how its shapes move.

    ``scene_dict`` is a Mitsuba scene dict (no sensor, no integrator); 4x4 numpy arrays in it
    become ``ScalarTransform4f`` in :meth:`to_dict`, so it does not depend on the variant.
    Scenes loaded from a file hold instantiated Mitsuba objects instead (tied to the variant).
    ``bboxes_mm`` holds each shape's world bounding box at t = 0 (min, max).
    """

    name: str
    scene_dict: dict
    motions: dict[str, Motion] = field(default_factory=dict)
    integrator: Any = field(default_factory=lambda: {"type": "path", "max_depth": 3})
    bboxes_mm: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    depths_mm: dict[str, float] = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    source: str | None = None

    @property
    def moving_ids(self) -> list[str]:
        """Ids of the shapes that move."""
        return sorted(k for k, m in self.motions.items() if not m.is_static)

    @property
    def is_static(self) -> bool:
        return not self.moving_ids

    def to_dict(self, sensor: Any = None, integrator: Any = None) -> dict:
        """The Mitsuba scene dict with ``sensor`` (a dict or object) and the integrator."""
        d = _to_mitsuba(self.scene_dict)
        chosen = integrator if integrator is not None else self.integrator
        if chosen is not None:  # a None value in the dict crashes mi.load_dict (segfault)
            d["integrator"] = _to_mitsuba(chosen)
        if sensor is not None:
            d["sensor"] = _to_mitsuba(sensor)
        return d

    def load(self, sensor: Any = None, integrator: Any = None):
        """``mi.Scene`` with mesh merging off, so that every moving shape keeps its id."""
        mi = _mi()
        return mi.load_dict(self.to_dict(sensor, integrator), optimize=False)

    def animator(self, scene) -> SceneAnimator:
        return SceneAnimator(scene, self)


def _to_mitsuba(obj: Any) -> Any:
    """Copy of a plain scene dict with 4x4 numpy arrays as ``mi.ScalarTransform4f``."""
    if isinstance(obj, dict):
        return {k: _to_mitsuba(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray) and obj.shape == (4, 4):
        return _mi().ScalarTransform4f(obj.tolist())
    return obj


def is_static(scene: SceneDescription) -> bool:
    """True when nothing in ``scene`` moves (one render pass, no geometry updates)."""
    return scene.is_static


class SceneAnimator:
    """Moves the shapes of a loaded scene to time t (ms) via ``mi.traverse``.

    Meshes are moved through ``<id>.vertex_positions`` (from a copy of the t = 0 vertices, so
    no error accumulates), other shapes through ``<id>.to_world``. A static scene never
    touches the parameters; ``n_updates`` counts ``params.update()`` calls (each rebuilds the
    BVH). The scene starts at t = 0.
    """

    def __init__(self, scene, description: SceneDescription):
        self.motions = {k: description.motions[k] for k in description.moving_ids}
        self.n_updates = 0
        self.t_ms = 0.0
        self.params = None
        self._keys: dict[str, str] = {}
        self._rest: dict[str, np.ndarray] = {}
        if self.motions:
            self._bind(scene)

    def _bind(self, scene) -> None:
        mi = _mi()
        params = mi.traverse(scene)
        for sid in self.motions:
            key = next(
                (f"{sid}.{s}" for s in ("vertex_positions", "to_world") if f"{sid}.{s}" in params),
                None,
            )
            if key is None:
                raise ParameterError(
                    f"moving shape {sid!r} is not among the scene's parameters; was it merged "
                    "with another mesh? Load scenes with SceneDescription.load()"
                )
            self._keys[sid] = key
        params.keep(list(self._keys.values()))
        for sid, key in self._keys.items():
            if key.endswith("vertex_positions"):
                self._rest[sid] = np.array(params[key], dtype=np.float64).reshape(-1, 3)
            else:
                self._rest[sid] = np.array(params[key].matrix, dtype=np.float64).reshape(4, 4)
        self.params = params

    def set_time(self, t_ms: float) -> bool:
        """Move every moving shape to ``t_ms``; returns whether the geometry was updated."""
        t = check_finite("t_ms", t_ms)
        if not self.motions or t == self.t_ms:
            return False
        mi = _mi()
        for sid, key in self._keys.items():
            m = self.motions[sid].matrix_at(t)
            rest = self._rest[sid]
            if key.endswith("vertex_positions"):
                p = rest @ m[:3, :3].T + m[:3, 3]
                self.params[key] = mi.Float(p.astype(np.float32).ravel())
            else:
                self.params[key] = type(self.params[key])((m @ rest).tolist())
        self.params.update()
        self.n_updates += 1
        self.t_ms = t
        return True


def _bbox_corners(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    idx = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    return np.where(idx == 1, hi, lo)


def fastest_image_speed_px_per_ms(
    scene: SceneDescription,
    camera: CameraDesign,
    t_range_ms: tuple[float, float] | None = None,
    n_samples: int = 65,
) -> float:
    """Largest image speed (px/ms, in ``camera``'s pixels) of any moving shape over
    ``t_range_ms`` (default the camera's exposure [-T, T]), for choosing time steps.

    Tracks the 8 corners of each shape's t = 0 bounding box through its motion and projects
    them with the pinhole model: exact for translations; for rotations the corners lie at least
    as far from the pivot as the geometry, so the estimate errs high (the safe side).
    """
    if scene.is_static:
        return 0.0
    t0, t1 = t_range_ms if t_range_ms is not None else (-camera.T_ms, camera.T_ms)
    if not t1 > t0:
        raise ParameterError(f"t_range_ms must be increasing, got {t_range_ms!r}")
    ts = np.linspace(t0, t1, max(int(n_samples), 2))
    best = 0.0
    for sid in scene.moving_ids:
        if sid not in scene.bboxes_mm:
            raise ParameterError(f"no bounding box known for moving shape {sid!r}")
        corners = _bbox_corners(*scene.bboxes_mm[sid])
        uv = np.stack([project_px(scene.motions[sid].apply(corners, t), camera) for t in ts])
        speed = np.linalg.norm(np.diff(uv, axis=0), axis=-1) / np.diff(ts)[:, None]
        best = max(best, float(speed.max()))
    return best


# ============================================================================================
# Building blocks of the built-in scenes
# ============================================================================================
def look_at(origin, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """Mitsuba's look_at as a numpy 4x4: local +z towards ``target``."""
    o, t, u = (np.asarray(x, float) for x in (origin, target, up))
    d = (t - o) / np.linalg.norm(t - o)
    left = np.cross(u, d)
    left /= np.linalg.norm(left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, np.cross(d, left), d, o
    return m


def _bitmap(path: Path, **extra) -> dict:
    return {"type": "bitmap", "filename": str(path), "filter_type": "bilinear", **extra}


def _mesh(assets: Path, stem: str, texture: str, smooth: bool = False) -> dict:
    return {
        "type": "ply",
        "filename": str(assets / f"{stem}.ply"),
        "face_normals": not smooth,  # box-like parts: flat facets; no normals in the PLY
        "bsdf": {"type": "diffuse", "reflectance": _bitmap(assets / f"{texture}.png")},
    }


@dataclass(frozen=True)
class _Light:
    position_mm: tuple[float, float, float]
    size_mm: float


def _lights(lights: list[_Light], target_mm, irradiance: float = WHITE_IRRADIANCE) -> dict:
    """Square area lights aimed at ``target_mm``, with one radiance chosen so that a surface
    there facing the camera receives ``irradiance`` (small-source estimate)."""
    t = np.asarray(target_mm, float)
    geom = 0.0
    for li in lights:
        d = np.asarray(li.position_mm) - t
        dist = np.linalg.norm(d)
        geom += li.size_mm**2 * (-d[2] / dist) / dist**2  # A cos(surface) / d^2, cos(light) = 1
    radiance = float(irradiance / geom)
    out = {}
    for k, li in enumerate(lights):
        s = np.diag([li.size_mm / 2, li.size_mm / 2, 1.0, 1.0])
        out[f"light_{k}"] = {
            "type": "rectangle",
            "to_world": look_at(li.position_mm, t) @ s,
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}},
        }
    return out


def _bboxes(assets: Path, stems) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    files = sa.load_manifest(assets)["files"]
    return {s: tuple(np.array(b) for b in files[f"{s}.ply"]["bounds_mm"]) for s in stems}


def train_scene(
    far_speed_px_per_ms: float = 1.0,
    near_speed_px_per_ms: float = 1.4,
    cache_dir: str | Path | None = None,
) -> SceneDescription:
    """The paper's train set (Section 4, Fig. 11): backdrop 505, far track 500, near track 495,
    car 490 mm (camera-facing sides). The far train moves right and the near train left in the
    image, at the given speeds in the *prototype's* 1280-px image, converted to mm/ms with
    |alpha| = f_px / Z at each track's depth."""
    check_positive("far_speed_px_per_ms", far_speed_px_per_ms, "px/ms")
    check_positive("near_speed_px_per_ms", near_speed_px_per_ms, "px/ms")
    assets = sa.ensure_assets(cache_dir)
    cam = prototype()
    v_far = image_to_scene_velocity(far_speed_px_per_ms, sa.FAR_TRACK_Z_MM, cam)
    v_near = image_to_scene_velocity(-near_speed_px_per_ms, sa.NEAR_TRACK_Z_MM, cam)
    shapes = {
        "backdrop": _mesh(assets, "backdrop", "backdrop"),
        "far_track": _mesh(assets, "far_track", "track"),
        "near_track": _mesh(assets, "near_track", "track"),
        "far_train": _mesh(assets, "far_train", "far_train"),
        "near_train": _mesh(assets, "near_train", "near_train"),
        "car": _mesh(assets, "car", "car"),
    }
    lights = [
        _Light((190.0, 230.0, 120.0), 160.0),
        _Light((-190.0, 230.0, 120.0), 160.0),
        _Light((0.0, -260.0, 150.0), 120.0),
    ]
    return SceneDescription(
        name="train",
        scene_dict={"type": "scene", **shapes, **_lights(lights, (0.0, 0.0, 500.0))},
        motions={"far_train": Motion(tuple(v_far)), "near_train": Motion(tuple(v_near))},
        bboxes_mm=_bboxes(assets, shapes),
        depths_mm={
            "backdrop": sa.BACKDROP_Z_MM,
            "far_track": sa.FAR_TRACK_Z_MM,
            "far_train": sa.FAR_TRACK_Z_MM,
            "near_track": sa.NEAR_TRACK_Z_MM,
            "near_train": sa.NEAR_TRACK_Z_MM,
            "car": sa.CAR_Z_MM,
        },
        info={
            "image_speed_px_per_ms (prototype)": {
                "far_train": far_speed_px_per_ms,
                "near_train": -near_speed_px_per_ms,
            },
            "depth convention": "z of the camera-facing side",
        },
    )


def soccer_scene(
    speed_px_per_ms: float = SOCCER_SPEED_PX_PER_MS, cache_dir: str | Path | None = None
) -> SceneDescription:
    """A football (radius 110 mm) centred at 1000 mm moving left to right (Fig. 16) in front
    of a brick wall at 1600 mm; default 1.0 px/ms in the prototype's image (0.66 m/s)."""
    check_positive("speed_px_per_ms", speed_px_per_ms, "px/ms")
    assets = sa.ensure_assets(cache_dir)
    z = sa.BALL_CENTRE_MM[2]
    v = image_to_scene_velocity(speed_px_per_ms, z, prototype())
    wall = _mesh(assets, "soccer_wall", "brick")
    ball = _mesh(assets, "soccer_ball", "soccer_ball", smooth=True)
    lights = [
        _Light((500.0, 700.0, 300.0), 400.0),
        _Light((-500.0, 700.0, 300.0), 400.0),
        _Light((0.0, -600.0, 300.0), 300.0),
    ]
    return SceneDescription(
        name="soccer",
        scene_dict={"type": "scene", "wall": wall, "ball": ball, **_lights(lights, (0, 0, z))},
        motions={"ball": Motion(tuple(v))},
        bboxes_mm={
            "ball": _bboxes(assets, ["soccer_ball"])["soccer_ball"],
            "wall": _bboxes(assets, ["soccer_wall"])["soccer_wall"],
        },
        depths_mm={"ball": z, "wall": sa.SOCCER_WALL_Z_MM},
        info={
            "image_speed_px_per_ms (prototype)": speed_px_per_ms,
            "depth convention": "centre of the ball",
        },
    )


def _limb_keyframes(name: str, t_max_ms: float, step_ms: float):
    """Rotation about the z axis from the t = 0 angle, sampled every ``step_ms``."""
    ts = np.arange(-t_max_ms, t_max_ms + step_ms / 2, step_ms)
    d = sa.limb_angle_rad(name, ts) - sa.limb_angle_rad(name, 0.0)
    out = []
    for t, a in zip(ts, d):
        m = np.eye(4)
        m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
        out.append((float(t), m))
    return tuple(out)


def walker_scene(
    speed_mm_per_ms: float = WALKER_SPEED_MM_PER_MS,
    cache_dir: str | Path | None = None,
    keyframe_range_ms: float = 150.0,
    keyframe_step_ms: float = 5.0,
) -> SceneDescription:
    """A person (1.67 m) centred at 3000 mm walking right to left (Fig. 17) at 1.4 m/s, in
    front of a brick wall at 4500 mm on a grass floor. Rigid body plus four limbs swinging
    about hip and shoulder (keyframed within +-``keyframe_range_ms``)."""
    check_positive("speed_mm_per_ms", speed_mm_per_ms, "mm/ms")
    check_positive("keyframe_range_ms", keyframe_range_ms, "ms")
    check_positive("keyframe_step_ms", keyframe_step_ms, "ms")
    assets = sa.ensure_assets(cache_dir)
    v = (speed_mm_per_ms, 0.0, 0.0)  # +x: towards the image's left
    parts = ["walker_body", *sa.walker_pivots()]
    shapes = {
        "wall": _mesh(assets, "walker_wall", "brick"),
        "floor": _mesh(assets, "walker_floor", "grass"),
    }
    shapes.update({p: _mesh(assets, p, "walker") for p in parts})
    motions = {"walker_body": Motion(v)}
    for name, pivot in sa.walker_pivots().items():
        kf = _limb_keyframes(name, keyframe_range_ms, keyframe_step_ms)
        motions[name] = Motion(v, kf, pivot)
    z, f_px = sa.WALKER_Z_MM, prototype().focal_length_px
    lights = [
        _Light((1500.0, 2000.0, 800.0), 1200.0),
        _Light((-1500.0, 2000.0, 800.0), 1200.0),
        _Light((0.0, -600.0, 600.0), 800.0),
    ]
    bb = _bboxes(assets, ["walker_wall", "walker_floor", *parts])
    bb["wall"], bb["floor"] = bb.pop("walker_wall"), bb.pop("walker_floor")
    return SceneDescription(
        name="walker",
        scene_dict={"type": "scene", **shapes, **_lights(lights, (0, 0, z))},
        motions=motions,
        bboxes_mm=bb,
        depths_mm={"walker": z, "wall": sa.WALKER_WALL_Z_MM},
        info={
            "speed_mm_per_ms": speed_mm_per_ms,
            "image_speed_px_per_ms (prototype)": -speed_mm_per_ms * f_px / z,
            "gait_period_ms": sa.GAIT_PERIOD_MS,
            "depth convention": "centre of the body",
        },
    )


def psf_scene(
    depth_mm: float,
    velocity_px_per_ms=0.0,
    *,
    velocity_mm_per_ms=None,
    radius_mm: float | None = None,
    offset_mm: tuple[float, float] = (0.0, 0.0),
    camera: CameraDesign | None = None,
    radiance: float | None = None,
) -> SceneDescription:
    """A tiny one-sided disk emitter facing the camera, on black, at ``depth_mm``.

    Velocity: ``velocity_px_per_ms`` in ``camera``'s image (a number: along the rows, + to the
    right; or (du, dv)), or ``velocity_mm_per_ms`` in the scene (a 3-vector), not both.
    ``radius_mm`` defaults to 0.25 px of ``camera`` (default: the prototype) at that depth;
    ``radiance`` defaults to 1 / (pi r_px^2), so the disk's image sums to ~1 in ``camera``'s
    pixels. The shape id is ``psf_disk``; it moves via ``psf_disk.to_world``. Render it with
    ``ptracer`` (the suggested integrator, max_depth 2) and a box reconstruction filter.
    """
    cam = camera or prototype()
    Z = check_positive("depth_mm", depth_mm, "mm")
    if velocity_mm_per_ms is not None:
        if np.any(np.asarray(velocity_px_per_ms, float) != 0):
            raise ParameterError("give velocity_px_per_ms or velocity_mm_per_ms, not both")
        v = np.asarray(velocity_mm_per_ms, float)
        if v.shape != (3,):
            raise ParameterError(f"velocity_mm_per_ms must be (vx, vy, vz) mm/ms, got {v!r}")
    else:
        v = image_to_scene_velocity(velocity_px_per_ms, Z, cam)
    px_per_mm = cam.focal_length_px / Z
    r = check_positive("radius_mm", radius_mm, "mm") if radius_mm is not None else 0.25 / px_per_mm
    r_px = r * px_per_mm
    L = check_positive("radiance", radiance) if radiance is not None else 1 / (math.pi * r_px**2)
    ox, oy = (check_finite("offset_mm", x) for x in offset_mm)
    # local +z (the emitting side) turned to -z, towards the camera; the disk has radius r
    to_world = np.array([[-r, 0, 0, ox], [0, r, 0, oy], [0, 0, -1.0, Z], [0, 0, 0, 1.0]])
    disk = {
        "type": "disk",
        "to_world": to_world,
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}},
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [L] * 3}},
    }
    lo, hi = np.array([ox - r, oy - r, Z]), np.array([ox + r, oy + r, Z])
    return SceneDescription(
        name="psf",
        scene_dict={"type": "scene", "psf_disk": disk},
        motions={"psf_disk": Motion(tuple(float(x) for x in v))},
        integrator={"type": "ptracer", "max_depth": 2},
        bboxes_mm={"psf_disk": (lo, hi)},
        depths_mm={"psf_disk": Z},
        info={"radius_mm": r, "radius_px": r_px, "radiance": L, "velocity_mm_per_ms": v.tolist()},
    )


BUILTIN_SCENES = {"train": train_scene, "soccer": soccer_scene, "walker": walker_scene}


# ============================================================================================
# Loading by name or path; XML export
# ============================================================================================
def load_scene(
    name_or_path: str | os.PathLike,
    *,
    cache_dir: str | Path | None = None,
    params: dict | None = None,
    **options,
) -> SceneDescription:
    """A built-in scene by name (``options`` go to its builder, e.g. ``far_speed_px_per_ms``)
    or a Mitsuba XML scene file (``params`` fill its ``$name`` parameters; motion comes from a
    ``<stem>.motion.json`` beside it, if any)."""
    key = os.fspath(name_or_path)
    if key in BUILTIN_SCENES:
        try:
            return BUILTIN_SCENES[key](cache_dir=cache_dir, **options)
        except TypeError as exc:
            raise ParameterError(f"invalid option for scene {key!r}: {exc}") from exc
    path = Path(key)
    if path.suffix.lower() != ".xml" and not path.exists():
        raise ParameterError(
            f"unknown scene {key!r}; valid names: {', '.join(sorted(BUILTIN_SCENES))}, "
            "or a path to a Mitsuba .xml scene file"
        )
    if options:
        raise ParameterError(f"options {sorted(options)} apply to built-in scenes only")
    return load_scene_file(path, cache_dir=cache_dir, params=params)


def _motion_file(path: Path) -> Path:
    return path.with_name(path.stem + ".motion.json")


def load_scene_file(
    path: str | Path, *, cache_dir: str | Path | None = None, params: dict | None = None
) -> SceneDescription:
    """A Mitsuba XML scene without its sensor (dropped), plus ``<stem>.motion.json``.

    The description holds the instantiated objects (for the active variant); every ``load()``
    reuses them, so keep one loaded scene per description at a time."""
    mi = _mi()
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"scene file not found: {str(path)!r}")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"cannot read scene file {str(path)!r}: {exc}") from exc
    kwargs = {k: str(v) for k, v in (params or {}).items()}
    if "$assets" in text and "assets" not in kwargs:  # our exported scenes use the cache
        kwargs["assets"] = str(sa.ensure_assets(cache_dir))
    try:
        loaded = mi.load_file(str(path), optimize=False, **kwargs)
    except Exception as exc:  # Mitsuba raises RuntimeError (parse) or others (plugins)
        raise ParameterError(f"scene file {str(path)!r} does not load: {exc}") from exc
    desc = _describe_loaded(loaded, path)
    mpath = _motion_file(path)
    if mpath.is_file():
        _apply_motion_file(desc, mpath)
    return desc


def _describe_loaded(loaded, path: Path) -> SceneDescription:
    """Sensor-free dict of the loaded objects (shapes carry their area lights)."""
    d: dict[str, Any] = {"type": "scene"}
    bboxes = {}
    for k, shape in enumerate(loaded.shapes()):
        sid = shape.id() or f"shape_{k}"
        d[sid] = shape
        b = shape.bbox()
        bboxes[sid] = (np.array(b.min, float).ravel(), np.array(b.max, float).ravel())
    for k, em in enumerate(loaded.emitters()):
        if em.get_shape() is None:  # area lights come with their shapes
            d[em.id() or f"emitter_{k}"] = em
    integrator = loaded.integrator() or {"type": "path", "max_depth": 3}
    return SceneDescription(
        name=path.stem,
        scene_dict=d,
        integrator=integrator,
        bboxes_mm=bboxes,
        source=str(path),
    )


def _apply_motion_file(desc: SceneDescription, mpath: Path) -> None:
    try:
        data = json.loads(mpath.read_text())
        shapes = data["shapes"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ParameterError(f"motion file {str(mpath)!r} is not valid: {exc}") from exc
    for sid, m in shapes.items():
        if sid not in desc.scene_dict:
            raise ParameterError(
                f"motion file {str(mpath)!r} moves {sid!r}, which the scene does not have; "
                f"shape ids: {', '.join(k for k in desc.scene_dict if k != 'type')}"
            )
        desc.motions[sid] = Motion.from_json(m)
    desc.depths_mm.update(data.get("depths_mm", {}))
    desc.info.update(data.get("info", {}))


_TAGS = {
    "shape": ("ply", "obj", "rectangle", "disk", "sphere", "cube", "cylinder"),
    "bsdf": ("diffuse", "twosided", "roughplastic", "plastic", "conductor"),
    "texture": ("bitmap", "checkerboard"),
    "emitter": ("area", "constant", "envmap"),
    "integrator": ("path", "ptracer", "direct"),
}


def _tag(plugin: str) -> str:
    for tag, types in _TAGS.items():
        if plugin in types:
            return tag
    raise ParameterError(f"cannot write plugin type {plugin!r} to XML")


def _xml(name: str, value: Any, assets: str, top: bool, pad: str) -> list[str]:
    if isinstance(value, dict):
        if value["type"] == "rgb":
            rgb = " ".join(repr(float(x)) for x in value["value"])
            return [f'{pad}<rgb name="{name}" value="{rgb}"/>']
        ident = f'id="{name}"' if top else f'name="{name}"'
        tag = _tag(value["type"])
        lines = [f'{pad}<{tag} type="{value["type"]}" {ident}>']
        for k, v in value.items():
            if k != "type":
                lines += _xml(k, v, assets, False, pad + "    ")
        return lines + [f"{pad}</{tag}>"]
    if isinstance(value, np.ndarray):
        flat = " ".join(repr(float(x)) for x in value.ravel())
        return [
            f'{pad}<transform name="{name}">',
            f'{pad}    <matrix value="{flat}"/>',
            f"{pad}</transform>",
        ]
    kind = {bool: "boolean", int: "integer", float: "float", str: "string"}[type(value)]
    text = str(value).lower() if isinstance(value, bool) else str(value)
    if isinstance(value, str) and assets and text.startswith(assets):
        text = "$assets" + text[len(assets) :]
    return [f'{pad}<{kind} name="{name}" value="{text}"/>']


def scene_to_xml(desc: SceneDescription, assets_dir: str | Path | None = None) -> str:
    """Mitsuba XML of a built-in scene (no sensor); asset paths become ``$assets/...``."""
    assets = str(Path(assets_dir)) if assets_dir else str(sa.asset_dir())
    lines = [
        '<scene version="3.0.0">',
        "    <!-- Generated by `python -m pacam_render.scenes --write`; do not edit. -->",
        "    <!-- Millimetres. Camera: origin, looking down +z, +y up (add a sensor). -->",
        "    <!-- $assets: the asset cache; pacam_render.load_scene fills it in. -->",
        '    <default name="assets" value="assets"/>',
    ]
    lines += _xml("integrator", desc.integrator, assets, False, "    ")
    for k, v in desc.scene_dict.items():
        if k != "type":
            lines += _xml(k, v, assets, True, "    ")
    return "\n".join(lines + ["</scene>", ""])


def motion_to_json(desc: SceneDescription) -> str:
    """The ``<stem>.motion.json`` text of a scene (motion, nominal depths, notes)."""
    data = {
        "units": "mm, ms; the pose in the XML is t = 0 (mid-exposure)",
        "shapes": {k: desc.motions[k].to_json() for k in sorted(desc.motions)},
        "depths_mm": desc.depths_mm,
        "info": desc.info,
    }
    return _json(data) + "\n"


def _is_leaf(x: Any) -> bool:
    """A number, a string, or a list of numbers or of such lists: written on one line."""
    if isinstance(x, (int, float, str)):
        return True
    return isinstance(x, list) and all(
        isinstance(y, (int, float)) or (isinstance(y, list) and all(_is_leaf(z) for z in y))
        for y in x
    )


def _json(obj: Any, pad: str = "") -> str:
    """Indented JSON (sorted keys) with leaves, and dicts of leaves, each on one line."""
    if _is_leaf(obj) or (isinstance(obj, dict) and all(map(_is_leaf, obj.values()))):
        return json.dumps(obj, sort_keys=True)
    inner = pad + " "
    if isinstance(obj, dict):
        items = [f"{inner}{json.dumps(k)}: {_json(obj[k], inner)}" for k in sorted(obj)]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    return "[\n" + ",\n".join(inner + _json(x, inner) for x in obj) + "\n" + pad + "]"


def write_scene_files(directory: str | Path = SCENE_DIR, cache_dir=None) -> list[Path]:
    """Export every built-in scene as ``<name>.xml`` + ``<name>.motion.json``."""
    out = []
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    for name in BUILTIN_SCENES:
        desc = load_scene(name, cache_dir=cache_dir)
        assets = sa.asset_dir(cache_dir)
        for p, text in (
            (d / f"{name}.xml", scene_to_xml(desc, assets)),
            (d / f"{name}.motion.json", motion_to_json(desc)),
        ):
            p.write_text(text)
            out.append(p)
    return out
