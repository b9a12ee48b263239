"""Writing a family scene: ``scene.xml`` (Mitsuba), ``scene.motion.json`` (what every command
reads beside it), ``textures/*.png`` and ``scene.json``, the card (:func:`generate_scene`), and
the asset cache of generated scenes (:func:`family_scene`).

Files are written atomically, JSON with sorted keys and floats to 9 significant digits, XML
with fixed 6-decimal numbers, PNGs with fixed settings: the same seed and parameters give
byte-identical files.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ...errors import ParameterError
from ...io.outputs import prepare_out_dir, write_text
from ..assets import cache_root
from .draw import FamilyObject, draw_objects
from .occlusion import MIN_OCCLUSION_MS, MIN_OVERLAP_PX, MIN_RELATIVE_SHIFT_PX, TIME_STEP_MS
from .spec import (
    DEPTH_SAMPLING,
    FAMILY_VERSION,
    check_family,
    check_seed,
    family_camera,
    is_family_name,
    params_to_json,
    parse_family_name,
    resolve_params,
)
from .textures import OBJECT_TEXTURE_PX, WALL_TEXTURE_PX, draw_texture, write_png

SCENE_FILES = ("scene.xml", "scene.motion.json", "scene.json", "textures")
"""What :func:`generate_scene` writes into its folder."""
WALL_MARGIN = 1.25
"""The wall covers the whole frame at its depth, this many times over (each side)."""
AMBIENT_RADIANCE = 1.0
"""Radiance of the constant environment light that lights the scene."""


def _clean(obj):
    """A JSON value with floats to 9 significant digits (and no -0.0), tuples as lists."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(f"{float(obj):.9g}") + 0.0
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def json_text(obj) -> str:
    """Deterministic JSON text (sorted keys, cleaned floats, one trailing newline)."""
    return json.dumps(_clean(obj), indent=1, sort_keys=True) + "\n"


def _n(x: float) -> str:
    return f"{float(x):.6f}"


def _bsdf(texture: str, pad: str) -> list[str]:
    return [
        f'{pad}<bsdf type="diffuse">',
        f'{pad}    <texture type="bitmap" name="reflectance">',
        f'{pad}        <string name="filename" value="{texture}"/>',
        f"{pad}    </texture>",
        f"{pad}</bsdf>",
    ]


def _facing(sx: float, sy: float, sz: float, centre) -> list[str]:
    """A transform that turns a shape to face the camera (-z), scales and places it."""
    x, y, z = centre
    return [
        '        <transform name="to_world">',
        f'            <scale x="{_n(sx)}" y="{_n(sy)}" z="{_n(sz)}"/>',
        '            <rotate y="1" angle="180"/>',
        f'            <translate x="{_n(x)}" y="{_n(y)}" z="{_n(z)}"/>',
        "        </transform>",
    ]


def _upright(r: float, length: float, base) -> list[str]:
    """Mitsuba's unit cylinder (axis 0 to 1 along z, radius 1) stood on ``base`` along +y,
    radius ``r``, as an exact matrix (local z to world y, local y to world -z). Not ``p0``/``p1``:
    Mitsuba builds that frame in float32 and, for some lengths, leaves a 1e-7 residue that its
    own check reports as shear and non-uniform scaling, once per load."""
    x, y, z = base
    m = [r, 0, 0, x, 0, 0, length, y, 0, -r, 0, z, 0, 0, 0, 1]
    return [
        '        <transform name="to_world">',
        f'            <matrix value="{" ".join(_n(v) for v in m)}"/>',
        "        </transform>",
    ]


def _shape_xml(sid: str, shape: str, centre, size_mm, texture: str) -> list[str]:
    """The ``<shape>`` element of one object (or the wall, a rectangle)."""
    w, h, d = size_mm
    x, y, z = centre
    lines = [f'    <shape type="{ {"box": "cube"}.get(shape, shape) }" id="{sid}">']
    if shape == "rectangle":
        lines += _facing(w / 2, h / 2, 1.0, centre)
    elif shape == "box":
        lines += _facing(w / 2, h / 2, d / 2, centre)
    elif shape == "sphere":
        lines += [
            f'        <point name="center" x="{_n(x)}" y="{_n(y)}" z="{_n(z)}"/>',
            f'        <float name="radius" value="{_n(w / 2)}"/>',
        ]
    else:  # cylinder: vertical axis through the centre, from y - h/2 up to y + h/2
        lines += _upright(w / 2, h, (x, y - h / 2, z))
    return lines + _bsdf(texture, "        ") + ["    </shape>"]


def scene_xml(family: str, seed: int, objects: list[FamilyObject], wall: dict) -> str:
    """The Mitsuba scene: the objects, the wall and a constant environment light."""
    lines = [
        '<scene version="3.0.0">',
        f"    <!-- pacam_render scene family {family!r} v{FAMILY_VERSION}, seed {seed}; "
        "mm, camera at the origin looking down +z; motion in scene.motion.json, card in "
        "scene.json -->",
    ]
    for o in objects:
        lines += _shape_xml(
            o.object_id, o.shape, o.centre_mm, o.size_mm, f"textures/{o.object_id}.png"
        )
    lines += _shape_xml(
        "wall", "rectangle", wall["centre_mm"], wall["size_mm"], wall["texture"]["file"]
    )
    lines += [
        '    <emitter type="constant">',
        f'        <rgb name="radiance" value="{_n(AMBIENT_RADIANCE)}"/>',
        "    </emitter>",
        "</scene>",
    ]
    return "\n".join(lines) + "\n"


def motion_json(family: str, seed: int, objects: list[FamilyObject], wall: dict) -> dict:
    """``scene.motion.json``: each moving object's velocity, every depth, and the family."""
    shapes = {
        o.object_id: {"velocity_mm_per_ms": list(o.velocity_mm_per_ms)}
        for o in objects
        if any(o.velocity_mm_per_ms)
    }
    depths = {o.object_id: o.depth_mm for o in objects}
    depths["wall"] = wall["centre_mm"][2]
    info = {"family": family, "family_version": FAMILY_VERSION, "seed": seed, "card": "scene.json"}
    return {"shapes": shapes, "depths_mm": depths, "info": info}


def _wall(p: dict, cam) -> dict:
    """The wall: a rectangle facing the camera at ``wall_depth_mm`` that covers the frame."""
    z = p["wall_depth_mm"]
    half_w = WALL_MARGIN * 0.5 * cam.width_px * z / cam.focal_length_px
    half_h = WALL_MARGIN * 0.5 * cam.height_px * z / cam.focal_length_px
    return {"centre_mm": (0.0, 0.0, z), "size_mm": (2 * half_w, 2 * half_h, 0.0)}


def _object_card(o: FamilyObject, texture: dict) -> dict:
    return {
        "id": o.object_id,
        "shape": o.shape,
        "depth_mm": o.depth_mm,
        "centre_mm": o.centre_mm,
        "centre_px": o.centre_px,
        "size_mm": o.size_mm,
        "size_px": o.size_px,
        "image_speed_px_per_ms": o.image_speed_px_per_ms,
        "direction_deg": o.direction_deg,
        "image_velocity_px_per_ms": o.image_velocity_px_per_ms,
        "velocity_mm_per_ms": o.velocity_mm_per_ms,
        "texture": texture,
    }


def _write_textures(out: Path, seed: int, attempt: int, objects, source: str) -> dict:
    """Each object's texture and the wall's, from the stream ``[seed, attempt, 1]``."""
    rng = np.random.default_rng([seed, attempt, 1])
    (out / "textures").mkdir(exist_ok=True)
    made = {}
    for sid, n_px in [(o.object_id, OBJECT_TEXTURE_PX) for o in objects] + [
        ("wall", WALL_TEXTURE_PX)
    ]:
        rgb, what = draw_texture(rng, source, n_px)
        name = f"textures/{sid}.png"
        write_png(out / name, rgb)
        made[sid] = {"file": name, "source": source, "kind": what, "size_px": n_px}
    return made


def files_digest(out: Path, names: list[str]) -> tuple[dict, str]:
    """sha256 of each file and one over all of them (names and bytes, in name order)."""
    each, total = {}, hashlib.sha256()
    for name in sorted(names):
        data = (out / name).read_bytes()
        each[name] = hashlib.sha256(data).hexdigest()
        total.update(name.encode() + b"\0" + data)
    return each, total.hexdigest()


def _card(family, seed, attempt, p, cam, objects, textures, wall, events, files) -> dict:
    each, digest = files
    return {
        "family": family,
        "family_version": FAMILY_VERSION,
        "seed": seed,
        "draw_attempt": attempt,
        "parameters": params_to_json(p),
        "camera": {
            "name": cam.name,
            "width_px": cam.width_px,
            "height_px": cam.height_px,
            "focal_length_px": cam.focal_length_px,
            "exposure_ms": cam.exposure_ms,
        },
        "conventions": {
            "depth_mm": "z of the object's centre; the camera at the origin looks down +z",
            "depth_sampling": DEPTH_SAMPLING[family],
            "image": "u to the right, v down, px at the camera's scale; scene +x is image left",
            "times": "ms over the exposure [-T, T], t = 0 at mid-exposure",
        },
        "objects": [_object_card(o, textures[o.object_id]) for o in objects],
        "wall": {"id": "wall", **wall, "texture": textures["wall"]},
        "occlusion_events": events,
        "occlusion_rules": {
            "footprint": "fronto-parallel section through the centre (disc for a sphere)",
            "time_step_ms": TIME_STEP_MS,
            "passes_min_overlap_px": MIN_OVERLAP_PX,
            "passes_min_duration_ms": MIN_OCCLUSION_MS,
            "passes_min_relative_shift_px": MIN_RELATIVE_SHIFT_PX,
            "wall": "every object is in front of the wall; those overlaps are not listed",
        },
        "files": each,
        "digest": digest,
    }


def generate_scene(family: str, seed: int, out_dir, *, force: bool = False, **params) -> Path:
    """Draw scene ``seed`` of ``family`` and write it into ``out_dir``.

    Parameters
    ----------
    family : str
        ``occluders``, ``depths`` or ``still`` (:data:`~.spec.FAMILIES`).
    seed : int
        A non-negative integer; the same seed and parameters give byte-identical files.
    out_dir : path-like
        The folder to write: ``scene.xml``, ``scene.motion.json``, ``scene.json`` (the card)
        and ``textures/``.
    force : bool, optional
        Overwrite a folder that already holds these files.
    **params
        The family's parameters (:func:`~.spec.resolve_params`), e.g.
        ``depth_range_mm=(400, 900)``, ``speed_range_px_per_ms=(0.2, 1.4)``.

    Returns
    -------
    Path
        The path of ``scene.xml``.

    Raises
    ------
    ParameterError
        A bad family, seed or parameter, or an output folder in use, before any drawing.
    """
    family, seed = check_family(family), check_seed(seed)
    p = resolve_params(family, **params)
    out = prepare_out_dir(out_dir, force, names=SCENE_FILES)
    cam = family_camera()
    objects, events, attempt = draw_objects(family, seed, p, cam)
    out.mkdir(parents=True, exist_ok=True)
    textures = _write_textures(out, seed, attempt, objects, p["textures"])
    wall = _wall(p, cam)
    write_text(
        out / "scene.xml",
        scene_xml(family, seed, objects, {**wall, "texture": textures["wall"]}),
        force=True,
    )
    write_text(
        out / "scene.motion.json", json_text(motion_json(family, seed, objects, wall)), force=True
    )
    names = ["scene.xml", "scene.motion.json", *(t["file"] for t in textures.values())]
    files = files_digest(out, names)
    card = _card(family, seed, attempt, p, cam, objects, textures, wall, events, files)
    write_text(out / "scene.json", json_text(card), force=True)
    return out / "scene.xml"


def params_digest(params: dict) -> str:
    """12 hex digits of the checked parameters, the cache's key."""
    return hashlib.sha256(json_text(params_to_json(params)).encode()).hexdigest()[:12]


def family_dir(family: str, seed: int, params: dict, cache_dir=None) -> Path:
    """Where :func:`family_scene` keeps a scene: ``<cache>/families/<family>-v<version>/
    seed<seed>-<params digest>``."""
    root = Path(cache_dir) if cache_dir is not None else cache_root()
    name = f"seed{seed}-{params_digest(params)}"
    return root / "families" / f"{family}-v{FAMILY_VERSION}" / name


def family_scene(
    name_or_family: str, seed=None, params: dict | None = None, cache_dir=None
) -> Path:
    """A family scene in the asset cache, generated on first use; its ``scene.xml``.

    Parameters
    ----------
    name_or_family : str
        ``family:NAME:SEED`` (then ``seed`` is left out), or a family's name.
    seed : int, optional
        The seed, with a family's name.
    params : dict, optional
        The family's parameters (:func:`~.spec.resolve_params`); default its defaults.
    cache_dir : path-like, optional
        The cache's root (default ``$PACAM_CACHE`` or ``~/.cache/pacam_render``).

    Returns
    -------
    Path
        ``scene.xml`` of the scene's folder, keyed by family, version, seed and parameters.
        It is written into a temporary folder and renamed, so concurrent callers never see
        half a scene.
    """
    family, seed = _family_and_seed(name_or_family, seed)
    p = resolve_params(family, **(params or {}))
    final = family_dir(family, seed, p, cache_dir)
    if (final / "scene.json").is_file():
        return final / "scene.xml"
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}-", dir=final.parent))
    try:
        generate_scene(family, seed, tmp, force=True, **p)
        try:
            os.rename(tmp, final)
        except OSError:  # another process won the race (or left an incomplete folder)
            if not (final / "scene.json").is_file():
                shutil.rmtree(final, ignore_errors=True)
                os.rename(tmp, final)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return final / "scene.xml"


def _family_and_seed(name_or_family: str, seed) -> tuple[str, int]:
    if is_family_name(name_or_family):
        if seed is not None:
            raise ParameterError(
                f"give the seed in the name {name_or_family!r} or as `seed`, not both"
            )
        return parse_family_name(name_or_family)
    if seed is None:
        raise ParameterError(
            f"family {name_or_family!r} needs a `seed` (or name it family:NAME:SEED)"
        )
    return check_family(name_or_family), check_seed(seed)
