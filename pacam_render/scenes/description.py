"""Scene descriptions: :class:`SceneDescription` (a Mitsuba scene dict without a sensor, a
suggested integrator, and a :class:`~.motion.Motion` per moving shape), :func:`load_scene_file`
for Mitsuba XML files with their ``<stem>.motion.json`` (:func:`~.builtin.load_scene` loads
built-in scenes by name too), :class:`SceneAnimator`, which moves a loaded scene's shapes in
time, and :func:`fastest_image_speed_px_per_ms`.

Load a description with :meth:`SceneDescription.load`: it turns Mitsuba's mesh merging off,
which would otherwise merge meshes that share a material and lose the shape ids that motion
refers to.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, check_finite, did_you_mean
from ..io.arrays import read_json
from ..limits import PacamWarning
from ..model.camera import CameraDesign
from . import assets as sa
from .motion import Motion, _bbox_corners, _mi, check_keys, project_px
from .scene_files import check_scene_files, check_scene_xml_size


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
    source_digest: str | None = None
    """A hash of what the scene was loaded from: a file scene's XML text, its parameters and
    every file it names (set by :func:`load_scene_file`); None for a scene built from a dict,
    whose :meth:`digest` hashes the dict and the files it names instead."""

    def digest(self) -> str:
        """A hash of every input of the scene (16 hex digits): what an XML attribute that
        ``mi.traverse`` does not expose (``flip_normals``, ``filter_type``, ``raw``, ...) or a
        file the scene reads changes, so that a checkpoint of another scene is not resumed."""
        if self.source_digest is not None:
            return self.source_digest
        h = hashlib.sha256()
        _hash_value(h, self.scene_dict)
        return h.hexdigest()[:16]

    def motion_digest(self) -> str:
        """A hash of the scene's motions (16 hex digits): its ``scene.motion.json``, or the
        built-in scene's, which :meth:`digest` leaves out."""
        motions = {k: self.motions[k].to_json() for k in sorted(self.motions)}
        text = json.dumps(motions, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

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


def _hash_value(h, obj: Any) -> None:
    """Feed a scene dict into ``h``: keys and values, arrays by their bytes, and the contents
    of every file a string names."""
    if isinstance(obj, dict):
        for k in sorted(obj):
            h.update(str(k).encode() + b"=")
            _hash_value(h, obj[k])
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            _hash_value(h, v)
    elif isinstance(obj, np.ndarray):
        h.update(obj.tobytes())
    elif isinstance(obj, str) and os.path.isfile(obj):
        h.update(obj.encode() + _file_sha(Path(obj)).encode())
    else:
        h.update(repr(obj).encode())
    h.update(b";")


def _file_sha(path: Path) -> str:
    d = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            d.update(chunk)
    return d.hexdigest()


_FILENAME = re.compile(r"""name\s*=\s*["']filename["']\s+value\s*=\s*["']([^"']+)["']""")
_INCLUDE = re.compile(r"""<include\s+filename\s*=\s*["']([^"']+)["']""")
_DEFAULT = re.compile(r"""<default\s+name\s*=\s*["'](\w+)["']\s+value\s*=\s*["']([^"']*)["']""")


def file_digest(path: Path, text: str, params: dict) -> str:
    """A hash of an XML scene's text, its ``$`` parameters and every file it names
    (``filename`` values and ``<include>``s, with ``$name`` filled from ``params`` or the
    scene's ``<default>``, relative to the XML's folder), 16 hex digits."""
    h = hashlib.sha256(text.encode())
    h.update(repr(sorted(params.items())).encode())
    values = {**dict(_DEFAULT.findall(text)), **params}
    names = _FILENAME.findall(text) + _INCLUDE.findall(text)
    for name in sorted(set(names)):
        filled = re.sub(r"\$(\w+)", lambda m: values.get(m.group(1), m.group(0)), name)
        target = Path(filled) if Path(filled).is_absolute() else path.parent / filled
        h.update(name.encode() + (_file_sha(target).encode() if target.is_file() else b"-"))
    return h.hexdigest()[:16]


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
    check_scene_xml_size(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"cannot read scene file {str(path)!r}: {exc}") from exc
    kwargs = {k: str(v) for k, v in (params or {}).items()}
    if "$assets" in text and "assets" not in kwargs:  # our exported scenes use the cache
        kwargs["assets"] = str(sa.ensure_assets(cache_dir))
    check_scene_files(path, text, kwargs)  # before Mitsuba reads any of them
    try:
        loaded = mi.load_file(str(path), optimize=False, **kwargs)
    except Exception as exc:  # Mitsuba raises RuntimeError (parse) or others (plugins)
        raise ParameterError(f"scene file {str(path)!r} does not load: {exc}") from exc
    desc = _describe_loaded(loaded, path)
    desc.source_digest = file_digest(path, text, kwargs)
    if "<sensor" in text:
        warnings.warn(
            f"the <sensor> of {path.name} is not used: pacam renders through its own camera "
            "(`mode`, `preset`); only the scene's shapes, emitters and integrator are kept",
            PacamWarning,
            stacklevel=3,
        )
    mpath = _motion_file(path)
    if mpath.is_file():
        _apply_motion_file(desc, mpath)
    else:
        _note_static(path)
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


MOTION_FILE_KEYS = ("shapes", "depths_mm", "info", "units")
"""The top-level keys of a ``<stem>.motion.json`` (``shapes`` required)."""


def _apply_motion_file(desc: SceneDescription, mpath: Path) -> None:
    """Motions and depths from ``mpath``; every key is checked, for a misspelt one would
    leave a shape still with no word."""
    data = read_json(mpath, "motion file")  # bounded in size and nesting, as records are
    what = f"motion file {str(mpath)!r}"
    check_keys(what, data, MOTION_FILE_KEYS, required=("shapes",))
    ids = sorted(desc.bboxes_mm)
    shapes = _shape_entries(f"{what}, 'shapes'", data["shapes"], ids)
    for sid, m in shapes.items():
        desc.motions[sid] = Motion.from_json(m, f"{what}, shape {sid!r}")
    depths = data.get("depths_mm", {})  # nominal depths, of shapes or of groups ("walker")
    if not isinstance(depths, dict):
        raise ParameterError(f"{what}, 'depths_mm' must be a JSON object, got {depths!r}")
    for sid, z in depths.items():
        name = f"{what}, depths_mm of {sid!r}"
        if isinstance(z, bool) or not isinstance(z, (int, float)):
            raise ParameterError(f"{name} must be a number (mm), got {z!r}")
        desc.depths_mm[sid] = check_finite(name, z)
    info = data.get("info", {})
    if not isinstance(info, dict):
        raise ParameterError(f"{what}, 'info' must be a JSON object, got {info!r}")
    desc.info.update(info)


def _shape_entries(what: str, d: Any, ids: list[str]) -> dict:
    """``d``, a JSON object keyed by shape ids, or an error naming a key that is no shape."""
    if not isinstance(d, dict):
        raise ParameterError(f"{what} must be a JSON object keyed by shape ids, got {d!r}")
    for sid in d:
        if sid not in ids:
            raise ParameterError(
                f"{what} names {sid!r}, which is no shape of the scene{did_you_mean(sid, ids)}; "
                f"shape ids: {', '.join(ids)}"
            )
    return d


def _note_static(path: Path) -> None:
    """A scene file without a motion file renders still: say so, and how to move a shape."""
    warnings.warn(
        f"{path.name} is static: no {_motion_file(path).name} beside it; to move a shape, "
        'write one: {"shapes": {"<shape id>": {"velocity_mm_per_ms": [vx, vy, vz]}}} '
        "(scenes/README.md, 'Scene files of your own')",
        PacamWarning,
        stacklevel=4,
    )


class SceneAnimator:
    """Moves the shapes of a loaded scene to time t (ms) via ``mi.traverse``.

    Meshes are moved through ``<id>.vertex_positions`` (from a copy of the t = 0 vertices, so
    no error accumulates), other shapes through ``<id>.to_world``. A static scene never
    touches the parameters; ``n_updates`` counts ``params.update()`` calls (each rebuilds the
    BVH). The scene starts at t = 0.

    Used as a context manager, it puts the shapes back at t = 0 when the block ends, however
    it ends: a description loaded from a scene file shares its mesh objects with every scene
    loaded from it (:func:`~pacam_render.scenes.files.load_scene_file`), so a render that
    stops with the meshes moved would leave the next scene (its truth, a store's truth) posed
    at the wrong time.
    """

    def __enter__(self) -> SceneAnimator:
        return self

    def __exit__(self, *exc) -> None:
        self.set_time(0.0)

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
