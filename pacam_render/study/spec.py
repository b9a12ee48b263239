"""Study specifications: a TOML file (or a built-in name) parsed once into typed points.

A study renders captures, passes them through the image sensor, deconvolves and scores them
(:mod:`.point`). Its TOML has four tables::

    [study]   name, report ("crossover", "speed" or "table"), description, decompose
    [render]  what every point shares: scene, preset, object_depth_mm (the depth the designs
              are made for), width, height, crop, noise_ratio (or spp), sampler,
              max_step_px, sensor, grey
    [grid]    axes, each a list: every combination is a point (or several [[grid]] tables:
              the union of their points)
    [quick]   overrides for --quick: a [quick.render] and a [quick.grid] table

and, instead of or beside ``[grid]``, an array ``[[points]]`` of single points. The axes are
:data:`AXES`. Points that differ only in light level, sensor or method share one render
(:meth:`Point.render_key`). Method ``none`` scores the capture as it is; any other restores it
with the mode's kernel (:func:`~pacam_render.restore.capture_score.kernel`). Every key is checked
before any work, and an error names it.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path

from ..errors import FileKeyError, ParameterError, did_you_mean
from ..exposure.camera import capture_design
from ..exposure.optics.diffraction import check_diffraction
from ..exposure.spec import CaptureSpec
from ..io.toml_file import check_keys, parse_toml, read_text, sub_table
from ..limits import note
from ..model.design_file import read_design
from ..model.illumination import parse_relative_illumination
from ..model.modes import MODES
from ..model.schedule_file import read_schedule
from ..render.variant import grey_request
from ..restore.capture_deblur import MODEL_ERRORS
from ..restore.deconvolve import METHODS, require_method
from ..scenes.builtin import BUILTIN_SCENES
from ..scenes.description import file_digest
from ..scenes.family.spec import family_seeds, is_family_name, parse_family_name
from ..sensor.model import SensorModel
from ..sensor.presets import mono_preset
from ..sensor.radiometry import DEFAULT_LIGHT_LEVEL, check_light_level

AXES = {
    "scene": "train",
    "mode": "coded",
    "design": "prototype",
    "speed_px_per_ms": None,
    "depth_mm": None,
    "light_level": DEFAULT_LIGHT_LEVEL,
    "sensor": None,
    "method": "hl",
    "seed": 0,
}
"""Sweepable axes and their defaults (None: the scene's own speed and depth, the render's
sensor). ``speed_px_per_ms``: image speed of the scene's fastest moving shape at t = 0 in the
preset's own pixels (the motions are scaled); ``depth_mm``: the moving shapes' depth (they are
moved along z, their image speed kept); ``light_level``: photons/px/ms of white through F2.8
(by default :data:`~pacam_render.sensor.radiometry.DEFAULT_LIGHT_LEVEL`, as for ``render`` and
``sensor``; ``optimize``'s is :data:`~pacam_render.optimize.search.DEFAULT_LIGHT_LEVEL`);
``design``: ``prototype`` (the preset), ``cover=S`` with optional ``,F=N`` or ``,r=PX``
(:func:`~pacam_render.model.design.solve`), ``schedule=PATH``: a designed schedule
(``pacam optimize``'s schedule.json), or a design file, ``PATH.toml`` or ``design=PATH``
(:mod:`~pacam_render.model.design_file`; the axis may list several)."""
RENDER = {
    "scene": "train",
    "preset": "prototype",
    "object_depth_mm": None,
    "width": 320,
    "height": 240,
    "crop": None,
    "spp": 64,
    "noise_ratio": 0.2,
    "sampler": "ldsampler",
    "max_step_px": 0.5,
    "sensor": "grasshopper-icx285",
}
"""Settings every point shares, and their defaults. ``noise_ratio``: each render is rendered
until its Monte Carlo sigma is at most this times the lowest sensor noise among the points it
feeds (0.2: the render adds at most 4 % to any point's noise variance); ``false`` renders
``spp`` samples instead, and so does a ``[render]`` table that gives ``spp`` without a
``noise_ratio`` (with both, ``spp`` is the target's first passes)."""
GREY_RENDER = "grey"
"""The ``[render]`` key (true or false, default false) that renders every capture in one
channel with Mitsuba's mono variant (:attr:`~pacam_render.exposure.spec.CaptureSpec.grey`;
``pacam study --grey`` sets it). A grey study's built-in colour sensor presets become their
monochrome twins (:data:`~pacam_render.sensor.presets.MONO_PRESETS`: ``grasshopper-icx285`` ->
``grasshopper-icx285-mono``, the same camera without its Bayer filter); a preset file with a
``bayer`` key is refused. It enters the study's keys only when true."""
RELATIVE_ILLUMINATION_RENDER = "relative_illumination"
"""The ``[render]`` key ``relative_illumination``: ``off`` (default), ``cos4`` or a curve file,
as :attr:`~pacam_render.exposure.spec.CaptureSpec.relative_illumination`. A point then
flat-fields the sensor's image (and the noise it tells the deconvolver) before it restores and
scores it, as a camera pipeline does. It enters the study's keys only when not ``off``."""
DIFFRACTION_RENDER = "diffraction"
"""The ``[render]`` key ``diffraction``: ``off`` (default), ``on`` or ``auto``, as
:attr:`~pacam_render.exposure.spec.CaptureSpec.diffraction`. It enters the study's keys
only when not ``off``; results.csv says per row whether the capture has it."""
LIGHTFIELD_RENDER = "lightfield"
"""The ``[render]`` key ``lightfield`` (true or false, default false): render one light-field
store per scene, speed, depth and seed, and synthesise every design and mode of the grid from
it (:mod:`pacam_render.lightfield`) instead of rendering each. The designs then share the
store's random numbers, so their differences are less noisy. A store is rendered to ``spp``
(``noise_ratio = false``); Levin's moving camera cannot be served. It enters the study's keys
only when true."""
QUICK_RENDER = {"width": 160, "height": 120, "crop": None, "spp": 16}
"""--quick for a study without a [quick] table: a small binned frame at 16 spp."""
REPORTS = ("crossover", "speed", "table")


@dataclass(frozen=True)
class Point:
    """One point of a study: a capture, a sensor, a deconvolution and a seed."""

    index: int
    scene: str
    mode: str
    design: str
    speed_px_per_ms: float | None
    depth_mm: float | None
    light_level: float
    sensor: str
    method: str
    seed: int

    def render_key(self) -> tuple:
        """What the render depends on: points with the same key share one capture."""
        return (self.scene, self.mode, self.design, self.speed_px_per_ms, self.depth_mm, self.seed)


@dataclass(frozen=True)
class StudySpec:
    """A parsed study: its name, report kind, shared render settings and points."""

    name: str
    report: str
    description: str
    render: dict
    points: tuple[Point, ...]
    source: str = ""
    axes: tuple[str, ...] = field(default=())
    decompose: bool = False
    """Score kernel-restored points three more ways (:mod:`.plateau`)."""
    model_error: str | float = "none"
    """What the deconvolver is told of the model error: ``none`` (default), ``oracle``, or a
    sigma calibrated on another capture (:mod:`~pacam_render.restore.capture_deblur`)."""
    quick: bool = False
    """Parsed for ``--quick``: the ``[quick]`` overrides (or :data:`QUICK_RENDER`) are in
    ``render`` and ``points``, and ``description`` still describes the full study."""

    def key(self) -> str:
        """A hash of everything that changes results, the contents of every file the points
        name (scene XMLs and what they read, schedules, sensor presets) included: a results
        folder belongs to one key, and a file rewritten between runs is another study."""
        blob = {"render": self.render, "points": [asdict(p) for p in self.points]}
        if self.decompose:
            blob["decompose"] = True
        blob.update(self._model_error_key())
        blob["files"] = input_digests(self.points)
        return _digest(blob)

    def point_keys(self) -> dict[int, str]:
        """{index: key} of every point: a hash of everything that determines its row.

        A point's row is a function of its own values (scene, mode, design, speed, depth,
        light level, sensor, method, seed; not its index), the render settings (the whole
        ``[render]`` table), ``decompose``, the contents of the files it names
        (:func:`input_digests`), and, with a ``noise_ratio``, the (sensor, light level) pairs
        of every point of its render (:func:`target_sensors`), since the render stops at the
        lowest of their noises (a render for some of them is given that target too,
        ``Task.group``). Nothing else reaches it: the render is bit-identical for a seed, the
        sensor's noise is drawn from the point's seed, the capture is applied to each point
        afresh, and a resumed render's checkpoint is keyed on its target. So, with the same
        package (which :meth:`key` assumes too), two points of equal key, in this spec or
        another, give the same row (its timings aside), and a row kept by key is what a fresh
        run of the point would write. Hashed as :meth:`key` is.
        """
        files = input_digests(self.points)
        out = {}
        for group in self.groups():
            sensors = target_sensors(group) if self.render.get("noise_ratio") else None
            for p in group:
                blob = {"render": self.render, "point": asdict(p), "target_sensors": sensors}
                del blob["point"]["index"]
                if self.decompose:
                    blob["decompose"] = True
                blob.update(self._model_error_key())
                named = [*_named_files(p), design_file_path(p.design)]  # the design file too
                blob["files"] = {n: files[n] for n in named if n in files}
                out[p.index] = _digest(blob)
        return out

    def _model_error_key(self) -> dict:
        """``model_error`` in the keys, except ``oracle``: rows written before the choice were
        the oracle's, and keep their keys."""
        return {} if self.model_error == "oracle" else {"model_error": self.model_error}

    def groups(self) -> list[tuple[Point, ...]]:
        """The points grouped by render, in order of their first point."""
        out: dict[tuple, list[Point]] = {}
        shared = self.render.get(LIGHTFIELD_RENDER)  # one store serves every design and mode
        for p in self.points:
            key = p.render_key()
            out.setdefault((key[0], *key[3:]) if shared else key, []).append(p)
        return [tuple(g) for g in out.values()]


def _digest(blob: dict) -> str:
    """16 hex digits of SHA-256 over ``blob`` as sorted JSON: the one hash of study keys."""
    return hashlib.sha256(json.dumps(blob, sort_keys=True).encode()).hexdigest()[:16]


def target_sensors(points) -> tuple[tuple[str, float], ...]:
    """The (sensor, light level) pairs whose lowest noise a render that feeds ``points`` is
    rendered to (:func:`~pacam_render.study.point.render_target`), sorted."""
    return tuple(sorted({(p.sensor, p.light_level) for p in points}))


def _named_files(p: Point) -> list[str]:
    """The names a point gives that may be files: its scene, sensor and schedule."""
    paths = [p.scene, p.sensor]
    if str(p.design).startswith("schedule="):
        paths.append(str(p.design)[len("schedule=") :])
    return paths


def input_digests(points) -> dict[str, str]:
    """{path: digest} of every file the points name: scene XMLs (with their motion JSON and
    every file they read), ``schedule=PATH`` designs, sensor preset files, and design files
    (the digest of the camera each makes, its bitmaps included)."""

    out = {}
    for p in points:
        for name in _named_files(p):
            path = Path(name)
            if name in out or not path.is_file():
                continue
            text = path.read_text(errors="replace")
            digest = file_digest(path, text, {}) if path.suffix.lower() == ".xml" else ""
            motion = path.with_name(path.stem + ".motion.json")
            extra = (
                motion.read_bytes() if path.suffix.lower() == ".xml" and motion.is_file() else b""
            )
            out[name] = hashlib.sha256(path.read_bytes() + digest.encode() + extra).hexdigest()[:16]
        design = design_file_path(p.design)
        if design is not None and design not in out:  # the camera it makes, bitmaps included
            out[design] = read_design(design).digest()
    return out


def builtin_studies() -> list[str]:
    """Names of the studies shipped with the package."""
    folder = resources.files("pacam_render.study") / "builtin"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_study(name_or_path: str, quick: bool = False, grey: bool = False) -> StudySpec:
    """A study by built-in name or TOML path, parsed and checked.

    ``grey=True`` (``pacam study --grey``) is ``grey = true`` in its ``[render]`` table
    (:data:`GREY_RENDER`).

    Examples
    --------
    >>> spec = load_study("crossover", quick=True)
    >>> spec.name, len(spec.points), spec.render["noise_ratio"]
    ('crossover', 9, 0.2)

    Raises
    ------
    ParameterError
        If the file is missing or not TOML, or any key or value is invalid; the message names
        the table and key.
    """
    path = Path(name_or_path)
    if name_or_path in builtin_studies():
        text = resources.files("pacam_render.study") / "builtin" / f"{name_or_path}.toml"
        text = text.read_text()
    elif path.suffix == ".toml" or path.exists():
        text = read_text(path, "study file")  # strictly UTF-8, a byte-order mark allowed
    else:
        raise ParameterError(
            f"unknown study {name_or_path!r}; built-in: {', '.join(builtin_studies())}, or a "
            "path to a .toml file"
        )
    return parse_study(_toml(text, name_or_path), quick, source=str(name_or_path), grey=grey)


def _toml(text: str, where: str) -> dict:
    return parse_toml(text, f"study {where!r}")


def parse_study(doc: dict, quick: bool = False, source: str = "", grey: bool = False) -> StudySpec:
    """:class:`StudySpec` from a TOML document (see the module docstring); ``grey=True`` sets
    ``grey = true`` in its ``[render]`` table.

    Raises
    ------
    FileKeyError
        Naming the table and key at fault (a TOML key, not the CLI flag of the same name).
    """
    try:
        return _parse(doc, quick, source, grey)
    except FileKeyError:
        raise
    except ParameterError as exc:
        raise FileKeyError(str(exc)) from None


def _parse(doc: dict, quick: bool, source: str, grey: bool = False) -> StudySpec:
    check_keys(doc, "the study file", {"study", "render", "grid", "points", "quick"})
    head = sub_table(doc, "study")
    check_keys(head, "[study]", {"name", "report", "description", "decompose", "model_error"})
    if not isinstance(head.get("decompose", False), bool):
        raise ParameterError(f"[study] decompose must be true or false, got {head['decompose']!r}")
    model_error = check_model_error(head.get("model_error", "none"))
    report = head.get("report", "table")
    if report not in REPORTS:
        raise ParameterError(f"[study] report must be one of {', '.join(REPORTS)}, got {report!r}")
    given = sub_table(doc, "render")
    render = {**RENDER, **given}
    if "spp" in given and "noise_ratio" not in given:  # the samples asked for, not a default
        render["noise_ratio"] = None  # target's (which took over with no word)
    grid, points = doc.get("grid", {}), doc.get("points", [])
    if quick:
        q = sub_table(doc, "quick")
        check_keys(q, "[quick]", {"render", "grid"})
        render.update(sub_table(q, "render", "[quick] render") if q else QUICK_RENDER)
        small = q.get("grid", {})
        both = isinstance(grid, dict) and isinstance(small, dict)
        grid = {**grid, **small} if both else small
    if grey:
        render["grey"] = True
    check_keys(
        render,
        "[render]",
        set(RENDER) | {"grey", DIFFRACTION_RENDER, RELATIVE_ILLUMINATION_RENDER, LIGHTFIELD_RENDER},
    )
    render = _check_render(render)
    base = Path(source).parent if source.lower().endswith(".toml") else None
    grid, points = _designs_beside(grid, base), _designs_beside(points, base)
    pts = _expand(grid, points, render)
    _check_lightfield(render, pts)
    return StudySpec(
        name=str(head.get("name", Path(source).stem or "study")),
        report=report,
        description=str(head.get("description", "")),
        render=render,
        points=pts,
        source=source,
        axes=tuple(k for k in AXES if len({getattr(p, k) for p in pts}) > 1),
        decompose=head.get("decompose", False),
        model_error=model_error,
        quick=bool(quick),
    )


def check_model_error(value) -> str | float:
    """``[study] model_error``: ``none``, ``oracle`` or a model sigma in [0, 10] (white = 1,
    calibrated on another capture of the camera, e.g. by ``pacam deconvolve
    --model-sigma-from``)."""

    if isinstance(value, str) and value in MODEL_ERRORS:
        return value
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not 0.0 <= float(value) <= 10.0:  # also NaN
        hint = did_you_mean(value, MODEL_ERRORS) if isinstance(value, str) else ""
        raise ParameterError(
            f"[study] model_error must be {' or '.join(MODEL_ERRORS)} or a model sigma in "
            f"[0, 10] (white = 1), got {value!r}{hint}"
        )
    return float(value)


def _check_lightfield(render: dict, points) -> None:
    """``[render] lightfield``: a bool; with it, no noise target, no moving camera and no
    diffraction ``on`` (a synthesised capture is geometric)."""
    if LIGHTFIELD_RENDER not in render:
        return
    on = render[LIGHTFIELD_RENDER]
    if not isinstance(on, bool):
        raise ParameterError(f"[render] lightfield must be true or false, got {on!r}")
    if not on:  # absent and false are the same study (and the same keys)
        del render[LIGHTFIELD_RENDER]
        return
    if render["noise_ratio"] is not None:
        raise ParameterError(
            "[render] lightfield renders each store to `spp`: give noise_ratio = false (a "
            "store is not rendered to a noise target yet)"
        )
    if render.get(DIFFRACTION_RENDER) == "on":  # every point's synthesis would refuse it
        raise ParameterError(
            '[render] lightfield = true with diffraction = "on": a capture synthesised from a '
            "store is geometric (diffraction is not linear in the aperture); give diffraction "
            '= "auto" or "off" (its effect is then measured), or lightfield = false'
        )
    levin = sorted({p.mode for p in points if p.mode == "levin"})
    if levin:
        raise ParameterError(
            "[render] lightfield cannot serve mode 'levin': Levin's camera moves its body, so "
            "its rays are not the store's; leave it out of the grid, or render directly"
        )


def _check_render(r: dict) -> dict:

    if r["crop"] in (False, None):
        r["crop"] = None
    elif not isinstance(r["crop"], list):
        raise ParameterError("[render] crop must be [x, y, w, h] (px) or false")
    ratio = r["noise_ratio"]
    if ratio in (False, None):
        r["noise_ratio"] = None
    elif isinstance(ratio, bool) or not isinstance(ratio, (int, float)) or not 0 < ratio <= 10:
        raise ParameterError(
            f"[render] noise_ratio must be a number in (0, 10] or false, got {ratio!r}"
        )
    try:
        CaptureSpec(
            scene="train",
            width=r["width"],
            height=r["height"],
            spp=r["spp"],
            sampler=r["sampler"],
            max_step_px=r["max_step_px"],
            preset=r["preset"],
            crop=tuple(r["crop"]) if r["crop"] else None,
            object_depth_mm=r["object_depth_mm"],
        )
    except ParameterError as exc:
        raise ParameterError(f"[render] {exc}") from None
    if DIFFRACTION_RENDER in r:
        try:
            check_diffraction(r[DIFFRACTION_RENDER])
        except ParameterError as exc:
            raise ParameterError(f"[render] {exc}") from None
        if r[DIFFRACTION_RENDER] == "off":  # absent and off: the same study and keys
            del r[DIFFRACTION_RENDER]
    if RELATIVE_ILLUMINATION_RENDER in r:
        try:
            ri = parse_relative_illumination(r[RELATIVE_ILLUMINATION_RENDER])
        except ParameterError as exc:
            raise ParameterError(f"[render] {exc}") from None
        r[RELATIVE_ILLUMINATION_RENDER] = ri.source
        if ri.kind == "off":  # absent and off: the same study and keys
            del r[RELATIVE_ILLUMINATION_RENDER]
    if "grey" in r:
        if not isinstance(r["grey"], bool):
            raise ParameterError(f"[render] grey must be true or false, got {r['grey']!r}")
        if not r["grey"]:  # absent and false are the same study (and the same keys)
            del r["grey"]
    if r.get("grey"):
        grey_request(True)  # refused with an RGB PACAM_VARIANT, before any work
    return {**r, "crop": list(r["crop"]) if r["crop"] else None}


def _grey_sensor(name):
    """A grey study's sensor: a built-in colour preset becomes its monochrome twin; a preset
    file with a Bayer filter is refused (GREY_RENDER)."""

    if not isinstance(name, str):
        return name  # _check_point names the bad value
    mono = mono_preset(name)
    if mono == name and name.lower().endswith((".json", ".toml")):
        model = SensorModel.from_preset(name)
        if model.bayer is not None:
            raise ParameterError(
                f"[render] grey = true renders grey captures, but sensor {name!r} has a colour "
                f"filter array (bayer {model.bayer!r}); give a preset without bayer, e.g. "
                f"grasshopper-icx285-mono"
            )
    return mono


def _combinations(grid: dict, where: str) -> list[dict]:
    if not isinstance(grid, dict):
        raise ParameterError(f"{where} must be a table of axes, got {type(grid).__name__}")
    check_keys(grid, where, set(AXES))
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise ParameterError(f"{where} {key} must be a non-empty list, got {values!r}")
    grid = dict(grid)
    if "scene" in grid:  # family:NAME:FIRST-LAST lists its seeds
        grid["scene"] = [
            n for v in grid["scene"] for n in (family_seeds(v) if isinstance(v, str) else [v])
        ]
    return [dict(zip(grid, vals)) for vals in itertools.product(*grid.values())]


def _expand(grid, points: list, render: dict) -> tuple[Point, ...]:
    if not grid and not points:  # else one point of defaults would run, asked for by no one
        raise ParameterError(
            "the study file names no points: give a [grid] table of axes (e.g. mode = "
            f'["coded", "normal"]) or [[points]]; axes: {", ".join(AXES)}'
        )
    grids = grid if isinstance(grid, list) else [grid] if grid or not points else []
    combos = []
    for k, g in enumerate(grids):
        combos += _combinations(g, "[grid]" if len(grids) == 1 else f"[[grid]] #{k + 1}")
    if not isinstance(points, list) or not all(isinstance(p, dict) for p in points):
        raise ParameterError("[[points]] must be an array of tables")
    for k, p in enumerate(points):
        check_keys(p, f"[[points]] #{k + 1}", set(AXES))
    out, seen = [], set()
    for combo in combos + points:
        values = {**AXES, "sensor": render["sensor"], "scene": render["scene"], **combo}
        if render.get("grey"):  # the camera without its colour filter (GREY_RENDER)
            values["sensor"] = _grey_sensor(values["sensor"])
        values = _check_point(values)
        frozen = tuple(sorted(values.items()))
        if frozen not in seen:
            seen.add(frozen)
            out.append(Point(index=len(out), **values))
    _check_designs(out, render)
    return tuple(out)


def _designs_beside(axes, base: Path | None):
    """The ``design`` values of a grid (or a list of grids or points) with their files
    (``PATH.toml``, ``design=PATH``, ``schedule=PATH``) resolved against the study file's
    folder, as a scene's includes are, and written relative to the working directory (the
    text a row records; unchanged when the study runs from its own folder). A file found only
    from the working directory (the old reading) is taken with a note."""
    if base is None or not axes:
        return axes
    if isinstance(axes, list):
        return [_designs_beside(a, base) if isinstance(a, dict) else a for a in axes]
    if not isinstance(axes, dict) or "design" not in axes:
        return axes
    d = axes["design"]
    values = [_beside(v, base) for v in (d if isinstance(d, list) else [d])]
    return {**axes, "design": values if isinstance(d, list) else values[0]}


def _beside(text, base: Path):
    t = str(text)
    if t.startswith("schedule="):
        prefix, path = "schedule=", t[len("schedule=") :]
    elif (path := design_file_path(t)) is not None:
        prefix = t[: len(t) - len(path)]  # "design=" or nothing
    else:
        return text
    if Path(path).is_absolute():
        return text
    here = base / path
    if here.exists():
        return prefix + os.path.relpath(here)
    if Path(path).exists():
        note(f"design {t!r} is not beside the study file ({here}); read from the working "
             "directory instead: write it relative to the study file")  # fmt: skip
    return text


def design_file_path(text) -> str | None:
    """The design file a ``design`` axis value names (``PATH.toml`` or ``design=PATH``)."""
    t = str(text)
    if t.startswith("design="):
        return t[len("design=") :]
    return t if t.lower().endswith(".toml") else None


def parse_design(text: str) -> dict:
    """``prototype``, ``cover=S[,F=N | ,r=PX]``, ``schedule=PATH`` (a ``pacam optimize``
    schedule.json) or a design file (``PATH.toml`` or ``design=PATH``) as CaptureSpec fields.

    Returns
    -------
    dict
        ``cover_px_per_ms`` (preset px/ms), ``f_number``, ``r_px`` and ``schedule``, each None
        if not given.
    """
    out = {"cover_px_per_ms": None, "f_number": None, "r_px": None, "schedule": None}
    if text == "prototype":
        return out
    path = design_file_path(text)
    if path is not None:
        read_design(path)  # checked with the spec, before any render
        return {**out, "design": path}
    if str(text).startswith("schedule="):
        path = str(text)[len("schedule=") :]
        read_schedule(path)  # checked with the spec, before any render
        return {**out, "schedule": path}
    names = {"cover": "cover_px_per_ms", "F": "f_number", "r": "r_px"}
    try:
        for part in str(text).split(","):
            k, v = part.split("=")
            out[names[k.strip()]] = float(v)
    except (ValueError, KeyError):
        raise ParameterError(
            f"design must be 'prototype' or 'cover=S' with optional ',F=N' or ',r=PX' (e.g. "
            f"'cover=1.4,F=5.6'), got {text!r}"
        ) from None
    if out["cover_px_per_ms"] is None:
        raise ParameterError(f"design {text!r} needs cover=S: F and r size a covering design")
    return out


def _check_point(v: dict) -> dict:

    where = f"point {json.dumps(v, default=str)}"
    if is_family_name(v["scene"]):
        try:
            parse_family_name(v["scene"])
        except ParameterError as exc:
            raise ParameterError(f"{where}: {exc}") from None
    elif v["scene"] not in BUILTIN_SCENES and not Path(v["scene"]).is_file():
        raise ParameterError(
            f"{where}: unknown scene {v['scene']!r}; valid: {', '.join(BUILTIN_SCENES)}, "
            "family:NAME:SEED (e.g. family:occluders:12) or an existing .xml file"
        )
    modes = [m for m in MODES if m != "reference"]
    if v["mode"] not in modes:
        raise ParameterError(f"{where}: unknown mode {v['mode']!r}; valid: {', '.join(modes)}")
    if v["method"] not in (*METHODS, "none"):
        raise ParameterError(
            f"{where}: unknown method {v['method']!r}; valid: {', '.join(METHODS)}, none"
        )
    try:  # an optional package missing fails here, not after the render
        require_method(v["method"])
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    parse_design(v["design"])
    for key, lo in (("speed_px_per_ms", 0.0), ("depth_mm", 1.0)):
        x = v[key]
        if x is None:
            continue
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not x > lo or x > 1e9:
            raise ParameterError(f"{where}: {key} must be a number in ({lo:g}, 1e9], got {x!r}")
        v[key] = float(x)
    x = v["light_level"]
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ParameterError(f"{where}: light_level must be a number, got {x!r}")
    try:
        v["light_level"] = check_light_level(x)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    if isinstance(v["seed"], bool) or not isinstance(v["seed"], int) or not 0 <= v["seed"] < 2**31:
        raise ParameterError(f"{where}: seed must be an integer in [0, 2^31), got {v['seed']!r}")

    SensorModel.from_preset(v["sensor"])  # raises, naming the presets
    return v


def _check_designs(points: list[Point], render: dict) -> None:
    """Every design can be built (the solver names the limit it hits), before any render."""

    for text in sorted({p.design for p in points}):
        try:
            depth = render["object_depth_mm"]
            capture_design(
                CaptureSpec(preset=render["preset"], object_depth_mm=depth, **parse_design(text))
            )
        except ParameterError as exc:
            raise ParameterError(f"design {text!r}: {exc}") from None
