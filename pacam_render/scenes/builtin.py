"""The built-in scenes: the paper's train set, a soccer ball and a walker (textured meshes
from :mod:`.assets`, lit by square area lights), and a PSF generator (:func:`psf_scene`).
:data:`BUILTIN_SCENES` maps their names to their builders; :func:`load_scene` loads a scene by
name, or from a Mitsuba XML file (:func:`~.description.load_scene_file`)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model.camera import CameraDesign, prototype
from . import assets as sa
from . import layout
from .description import SceneDescription, load_scene_file
from .family.spec import FAMILIES, is_family_name
from .family.write import family_scene
from .motion import Motion, image_to_scene_velocity, look_at

SCENE_DIR = Path(__file__).resolve().parents[2] / "scenes"
"""The repository's ``scenes/`` folder: XML files exported from the built-in scenes."""

WHITE_IRRADIANCE = 0.8 * math.pi
"""Irradiance of the built-in scenes' lights: a white diffuse surface reads a radiance of ~0.8."""
SOCCER_SPEED_PX_PER_MS = 1.0
"""The soccer ball's image speed, px/ms, in the prototype's image: 0.66 m/s at 1000 mm, a
hand-moved ball."""
WALKER_SPEED_MM_PER_MS = 1.4
"""The walker's speed, mm/ms: 1.4 m/s, a typical walking speed (0.70 px/ms at 3000 mm)."""


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
    v_far = image_to_scene_velocity(far_speed_px_per_ms, layout.FAR_TRACK_Z_MM, cam)
    v_near = image_to_scene_velocity(-near_speed_px_per_ms, layout.NEAR_TRACK_Z_MM, cam)
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
            "backdrop": layout.BACKDROP_Z_MM,
            "far_track": layout.FAR_TRACK_Z_MM,
            "far_train": layout.FAR_TRACK_Z_MM,
            "near_track": layout.NEAR_TRACK_Z_MM,
            "near_train": layout.NEAR_TRACK_Z_MM,
            "car": layout.CAR_Z_MM,
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
    z = layout.BALL_CENTRE_MM[2]
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
        depths_mm={"ball": z, "wall": layout.SOCCER_WALL_Z_MM},
        info={
            "image_speed_px_per_ms (prototype)": speed_px_per_ms,
            "depth convention": "centre of the ball",
        },
    )


def _limb_keyframes(name: str, t_max_ms: float, step_ms: float):
    """Rotation about the z axis from the t = 0 angle, sampled every ``step_ms``."""
    ts = np.arange(-t_max_ms, t_max_ms + step_ms / 2, step_ms)
    d = layout.limb_angle_rad(name, ts) - layout.limb_angle_rad(name, 0.0)
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
    parts = ["walker_body", *layout.walker_pivots()]
    shapes = {
        "wall": _mesh(assets, "walker_wall", "brick"),
        "floor": _mesh(assets, "walker_floor", "grass"),
    }
    shapes.update({p: _mesh(assets, p, "walker") for p in parts})
    motions = {"walker_body": Motion(v)}
    for name, pivot in layout.walker_pivots().items():
        kf = _limb_keyframes(name, keyframe_range_ms, keyframe_step_ms)
        motions[name] = Motion(v, kf, pivot)
    z, f_px = layout.WALKER_Z_MM, prototype().focal_length_px
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
        depths_mm={"walker": z, "wall": layout.WALKER_WALL_Z_MM},
        info={
            "speed_mm_per_ms": speed_mm_per_ms,
            "image_speed_px_per_ms (prototype)": -speed_mm_per_ms * f_px / z,
            "gait_period_ms": layout.GAIT_PERIOD_MS,
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
"""The built-in scenes by name, each a function that builds its description."""


def load_scene(
    name_or_path: str | os.PathLike,
    *,
    cache_dir: str | Path | None = None,
    params: dict | None = None,
    **options,
) -> SceneDescription:
    """A built-in scene by name (``options`` go to its builder, e.g. ``far_speed_px_per_ms``),
    a family scene ``family:NAME:SEED`` (generated once into the cache with the family's
    default parameters, :func:`~.family.family_scene`), or a Mitsuba XML scene file
    (``params`` fill its ``$name`` parameters; motion comes from a ``<stem>.motion.json``
    beside it, if any)."""
    key = os.fspath(name_or_path)
    if is_family_name(key):
        if options or params:
            raise ParameterError(
                f"scene {key!r} takes no options: a family scene is drawn with its family's "
                "defaults; generate one with other parameters (pacam scene generate) and load "
                "its scene.xml"
            )
        desc = load_scene_file(family_scene(key, cache_dir=cache_dir), cache_dir=cache_dir)
        desc.name = key
        return desc
    if key in BUILTIN_SCENES:
        try:
            return BUILTIN_SCENES[key](cache_dir=cache_dir, **options)
        except TypeError as exc:
            raise ParameterError(f"invalid option for scene {key!r}: {exc}") from exc
    path = Path(key)
    if path.suffix.lower() != ".xml" and not path.exists():
        raise ParameterError(
            f"unknown scene {key!r}; valid names: {', '.join(sorted(BUILTIN_SCENES))}, "
            f"family:NAME:SEED (families: {', '.join(FAMILIES)}), or a path to a Mitsuba .xml "
            "scene file"
        )
    if options:
        raise ParameterError(f"options {sorted(options)} apply to built-in scenes only")
    return load_scene_file(path, cache_dir=cache_dir, params=params)
