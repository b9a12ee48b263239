"""A dataset's TOML spec, parsed and checked: every error names the key and its valid range.

A spec names the scenes (a family and its seeds, or a list of scenes), the capture (sensor
size, window, samples or noise target), the cameras, the image sensor and its light levels,
the PSF's speed and how to render (direct, or through light-field stores). See
``docs/howto/dataset.md`` for every key.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..errors import FileKeyError, ParameterError, did_you_mean
from ..exposure.optics.diffraction import check_diffraction
from ..exposure.spec import CaptureSpec, check_crop
from ..io.toml_file import check_keys, read_toml, sub_table
from ..model.modes import MODES
from ..render.samplers import DEFAULT_SAMPLER, check_sampler
from ..scenes.builtin import BUILTIN_SCENES
from ..scenes.family import resolve_params
from ..sensor.model import SensorModel
from ..sensor.radiometry import check_light_level

STORE_CHOICES = ("auto", "always", "never")
"""``[run] store``: a light-field store per scene when the cameras exceed the break-even
(``auto``), always, or never (direct renders); a camera a store cannot serve renders
directly either way."""

TOP_KEYS = {"name", "seed", "scenes", "capture", "cameras", "sensor", "psf", "run"}
CAPTURE_KEYS = {
    "width", "height", "crop", "spp", "passes", "noise_ratio", "noise_target", "sampler",
    "max_step_px", "diffraction", "relative_illumination", "grey", "max_samples", "max_steps",
}  # fmt: skip
CAMERA_KEYS = {"name", "mode", "preset", "design", "cover_px_per_ms", "f_number", "r_px",
               "depth_mm", "lcos_contrast", "lcos_fill_factor", "lcos_switching_ms"}  # fmt: skip
LCOS_RANGES = {"lcos_contrast": (1.0, 1e9), "lcos_fill_factor": (1e-9, 1.0),
               "lcos_switching_ms": (0.0, 1e3)}  # fmt: skip
"""A camera's LCoS keys and their ranges (CaptureSpec's fields; a switching time is checked
against the camera's pattern time when the dataset is planned)."""
SCENE_KEYS = {"family", "seeds", "params", "list"}
SENSOR_KEYS = {"preset", "light_levels"}
PSF_KEYS = {"velocity_px_per_ms"}
RUN_KEYS = {"store", "max_disk_gib"}
MAX_SEED = 2**31


@dataclass(frozen=True)
class Camera:
    """One camera of the dataset: a name (unique, used in sample ids) and the
    :class:`~pacam_render.exposure.spec.CaptureSpec` fields that make it."""

    name: str
    fields: dict = field(default_factory=dict)


@dataclass(frozen=True)
class DatasetSpec:
    """A dataset spec (module docstring); built by :func:`parse_spec`.

    ``scenes`` are scene strings as :func:`~pacam_render.scenes.load_scene` takes them
    (``family:NAME:SEED`` for a family's seed); ``capture`` the CaptureSpec fields every
    sample shares; ``light_levels`` photons/px/ms of white through the full aperture.
    """

    scenes: tuple[str, ...]
    cameras: tuple[Camera, ...]
    capture: dict
    sensor: str
    light_levels: tuple[float, ...]
    seed: int = 0
    name: str = "dataset"
    family: str | None = None
    family_params: dict | None = None
    noise_ratio: float | None = None
    noise_target: float | None = None
    max_samples: int | None = None
    max_steps: int | None = None
    psf_velocity_px_per_ms: float = 0.0
    store: str = "auto"
    max_disk_gib: float = 20.0
    source: dict = field(default_factory=dict)
    """The TOML document as read, recorded in the card."""

    def key(self) -> str:
        """A hash of the whole spec (the folder's identity: another spec is refused)."""
        blob = json.dumps(asdict(self), sort_keys=True, default=str)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    @property
    def n_samples(self) -> int:
        return len(self.scenes) * len(self.cameras) * len(self.light_levels)


def load_spec(path) -> DatasetSpec:
    """The spec in the TOML file ``path``, checked (:func:`parse_spec`)."""
    doc = read_toml(path, "dataset spec")
    return parse_spec(doc, base=Path(path).parent)


def parse_spec(doc: dict, base: Path | None = None) -> DatasetSpec:
    """A spec from a parsed TOML document.

    Parameters
    ----------
    doc : dict
        The document (see ``docs/howto/dataset.md``).
    base : pathlib.Path, optional
        The spec's folder: relative scene and design paths are taken from there when they
        exist there.

    Raises
    ------
    FileKeyError
        Naming the key and its valid values, before any work.
    """
    try:
        return _parse(doc, base or Path("."))
    except FileKeyError:
        raise
    except ParameterError as exc:
        raise FileKeyError(str(exc)) from None


def _parse(doc: dict, base: Path) -> DatasetSpec:
    check_keys(doc, "the spec", TOP_KEYS)
    seed = _int(doc.get("seed", 0), "seed", 0, MAX_SEED - 1)
    name = doc.get("name", "dataset")
    if not isinstance(name, str) or not name:
        raise ParameterError(f"`name` must be a non-empty string, got {name!r}")
    scenes, family, params = _scenes(doc.get("scenes"), base)
    capture, sampling = _capture(sub_table(doc, "capture"))
    sensor, levels = _sensor(sub_table(doc, "sensor"))
    model = SensorModel.from_preset(sensor)
    if model.bayer is None and model.shot_noise:  # a monochrome sensor sees one channel
        capture["grey"] = True  # as `pacam render --sensor` renders for it
    cameras = _cameras(doc.get("cameras"), base, capture)
    psf = sub_table(doc, "psf")
    check_keys(psf, "[psf]", PSF_KEYS)
    v = _number(psf.get("velocity_px_per_ms", 0.0), "[psf] velocity_px_per_ms", -1e3, 1e3)
    run = sub_table(doc, "run")
    check_keys(run, "[run]", RUN_KEYS)
    store = run.get("store", "auto")
    if store not in STORE_CHOICES:
        raise ParameterError(
            f"[run] store must be one of {', '.join(STORE_CHOICES)}, got {store!r}"
            + did_you_mean(store, STORE_CHOICES)
        )
    disk = _number(run.get("max_disk_gib", 20.0), "[run] max_disk_gib", 1e-9, 1e6)
    return DatasetSpec(
        scenes=scenes, cameras=cameras, capture=capture, sensor=sensor, light_levels=levels,
        seed=seed, name=name, family=family, family_params=params, **sampling,
        psf_velocity_px_per_ms=v, store=store, max_disk_gib=disk, source=doc,
    )  # fmt: skip


def _scenes(value, base: Path) -> tuple[tuple[str, ...], str | None, dict | None]:
    """The scene strings: a list of scenes, or ``[scenes]`` with a family and its seeds."""
    if value is None:
        raise ParameterError(
            '`scenes` is missing: give scenes = ["train", ...] or a [scenes] table with '
            "family and seeds"
        )
    if isinstance(value, dict):
        check_keys(value, "[scenes]", SCENE_KEYS)
        if "list" in value:
            if set(value) - {"list"}:
                raise ParameterError("[scenes] list cannot go with family, seeds or params")
            return _scene_list(value["list"], "[scenes] list", base), None, None
        return _family(value)
    return _scene_list(value, "scenes", base), None, None


def _scene_list(value, where: str, base: Path) -> tuple[str, ...]:
    if not isinstance(value, list) or not value:
        raise ParameterError(f"`{where}` must be a non-empty list of scenes, got {value!r}")
    out = []
    for s in value:
        if not isinstance(s, str) or not s:
            raise ParameterError(f"`{where}` entries must be scene names or paths, got {s!r}")
        near = base / s
        scene = str(near) if not Path(s).is_absolute() and near.exists() else s
        if scene not in BUILTIN_SCENES and not scene.startswith("family:"):
            if not Path(scene).is_file():
                raise ParameterError(
                    f"`{where}`: no scene {s!r}: give a built-in scene "
                    f"({', '.join(sorted(BUILTIN_SCENES))}) or a scene file (beside the spec, "
                    "or from the current folder)"
                )
        out.append(scene)
    if len(set(out)) != len(out):
        raise ParameterError(f"`{where}` names a scene twice: each scene once")
    return tuple(out)


def _family(table: dict) -> tuple[tuple[str, ...], str, dict | None]:
    """``family:NAME:SEED`` strings for the seeds of ``[scenes]``."""
    family = table.get("family")
    if not isinstance(family, str) or not family or ":" in family:
        raise ParameterError(
            f'[scenes] family must be a family\'s name (e.g. "occluders"), got {family!r}'
        )
    seeds = table.get("seeds")
    if isinstance(seeds, list):
        if len(seeds) != 2:
            raise ParameterError(
                f"[scenes] seeds must be a count (8: seeds 0-7) or a range [first, last], "
                f"got {seeds!r}"
            )
        lo = _int(seeds[0], "[scenes] seeds[0]", 0, MAX_SEED - 1)
        hi = _int(seeds[1], "[scenes] seeds[1]", 0, MAX_SEED - 1)
        if hi < lo:
            raise ParameterError(f"[scenes] seeds: the range [{lo}, {hi}] is empty (last < first)")
        numbers = range(lo, hi + 1)
    else:
        numbers = range(_int(seeds, "[scenes] seeds", 1, 100_000))
    params = table.get("params")
    if params is not None and not isinstance(params, dict):
        raise ParameterError(f"[scenes] params must be a table, got {params!r}")
    try:  # the family and its parameters, checked before any scene is generated
        resolve_params(family, **(params or {}))
    except (ParameterError, TypeError) as exc:
        raise ParameterError(f"[scenes] family {family!r}, params: {exc}") from None
    return tuple(f"family:{family}:{s}" for s in numbers), family, params


def _capture(t: dict) -> tuple[dict, dict]:
    """The CaptureSpec fields every sample shares, and the sampling keys outside them."""
    check_keys(t, "[capture]", CAPTURE_KEYS)
    width = _int(t.get("width", 320), "[capture] width", 2, 100_000)
    height = _int(t.get("height", 240), "[capture] height", 2, 100_000)
    crop = t.get("crop")
    if crop is not None:
        crop = check_crop(crop, width, height)
    ratio, target = t.get("noise_ratio"), t.get("noise_target")
    if ratio is not None and target is not None:
        raise ParameterError("[capture] give noise_ratio or noise_target, not both")
    if "spp" in t and (ratio is not None or target is not None):
        raise ParameterError("[capture] spp and a noise target both set the samples: give one")
    fields = {
        "width": width, "height": height, "crop": crop,
        "spp": _int(t.get("spp", 64), "[capture] spp", 1, 2**30),
        "passes": _int(t.get("passes", 2), "[capture] passes", 2, 1024),
        "sampler": t.get("sampler", DEFAULT_SAMPLER),
        "max_step_px": _number(t.get("max_step_px", 0.5), "[capture] max_step_px", 1e-6, 1e6),
        "diffraction": t.get("diffraction", "auto"),
        "relative_illumination": t.get("relative_illumination", "cos4"),
        "grey": t.get("grey", False),
    }  # fmt: skip
    check_sampler(fields["sampler"])
    check_diffraction(fields["diffraction"])
    sampling = {
        "noise_ratio": None
        if ratio is None
        else _number(ratio, "[capture] noise_ratio", 1e-9, 1e9),
        "noise_target": None
        if target is None
        else _number(target, "[capture] noise_target", 1e-30, 1e30),
        "max_samples": None
        if "max_samples" not in t
        else _int(t["max_samples"], "[capture] max_samples", 1, 2**62),
        "max_steps": None
        if "max_steps" not in t
        else _int(t["max_steps"], "[capture] max_steps", 1, 10**9),
    }
    return fields, sampling


def _sensor(t: dict) -> tuple[str, tuple[float, ...]]:
    check_keys(t, "[sensor]", SENSOR_KEYS)
    preset = t.get("preset", "grasshopper-icx285")
    if not isinstance(preset, str):
        raise ParameterError(f"[sensor] preset must be a preset's name or file, got {preset!r}")
    try:
        SensorModel.from_preset(preset)
    except ParameterError as exc:
        raise ParameterError(f"[sensor] preset: {exc}") from None
    levels = t.get("light_levels", [300.0])
    if not isinstance(levels, list) or not levels:
        raise ParameterError(
            f"[sensor] light_levels must be a non-empty list of photons/px/ms > 0, got {levels!r}"
        )
    out = tuple(check_light_level(v, "[sensor] light_levels") for v in levels)
    if len(set(out)) != len(out):
        raise ParameterError("[sensor] light_levels lists a level twice")
    return preset, out


def _cameras(value, base: Path, capture: dict) -> tuple[Camera, ...]:
    if not isinstance(value, list) or not value:
        raise ParameterError(
            "`cameras` must be one or more [[cameras]] tables (name, mode, preset or design)"
        )
    cams = [_camera(c, i, base) for i, c in enumerate(value)]
    names = [c.name for c in cams]
    if len(set(names)) != len(names):
        raise ParameterError(f"[[cameras]] names must differ, got {names}")
    for c in cams:  # each camera checked as a capture, before any work
        CaptureSpec(**capture, **c.fields)
    return tuple(cams)


def _camera(c, i: int, base: Path) -> Camera:
    where = f"[[cameras]] #{i + 1}"
    if not isinstance(c, dict):
        raise ParameterError(f"{where} must be a table, got {c!r}")
    check_keys(c, where, CAMERA_KEYS)
    mode = c.get("mode", "coded")
    if mode not in MODES:
        raise ParameterError(
            f"{where} mode must be one of {', '.join(MODES)}, got {mode!r}"
            + did_you_mean(mode, MODES)
        )
    name = c.get("name", mode)
    if not isinstance(name, str) or not name.replace("-", "").replace("_", "").isalnum():
        raise ParameterError(f"{where} name must be letters, digits, - or _, got {name!r}")
    if "design" in c and "preset" in c:
        raise ParameterError(f"{where}: give design or preset, not both: each is the camera")
    design = c.get("design")
    if design is not None:
        near = base / str(design)
        design = str(near) if not Path(design).is_absolute() and near.exists() else design
    fields = {"mode": mode, "preset": c.get("preset", "prototype"), "design": design}
    for key, spec_key in (("cover_px_per_ms", "cover_px_per_ms"), ("f_number", "f_number"),
                          ("r_px", "r_px"), ("depth_mm", "object_depth_mm")):  # fmt: skip
        if key in c:
            fields[spec_key] = _number(c[key], f"{where} {key}", 1e-9, 1e9)
    for key, (lo, hi) in LCOS_RANGES.items():
        if key in c:
            fields[key] = _number(c[key], f"{where} {key}", lo, hi)
    return Camera(name, fields)


def _int(value, key: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ParameterError(f"`{key}` must be an integer in [{lo}, {hi}], got {value!r}")
    return value


def _number(value, key: str, lo: float, hi: float) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not lo <= value <= hi:
        raise ParameterError(f"`{key}` must be a number in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)
