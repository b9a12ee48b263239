"""A camera design on disk: one TOML file that every command takes (``--design FILE``).

The file holds everything that makes a camera, in the units of :class:`CameraDesign` (mm, ms,
px, deg)::

    format = 1
    name = "covers 2 px/ms"

    [sensor]                 # the image sensor
    width_px = 1280
    height_px = 960
    pixel_pitch_mm = 0.00645
    fov_deg = 46.0
    preset = "grasshopper-icx285"   # optional: its noise model (pacam sensor's presets)

    [lens]
    R_max_mm = 6.97344       # clear aperture radius (the whole LCoS disc), at F_min
    F_min = 2.8
    focus_distance_mm = 751.6

    [lcos]
    pitch_mm = 0.01362
    rate_fps = 365.0         # patterns per second the display can show

    [exposure]
    exposure_ms = 45.0       # 2T
    n_patterns = 16

    [opening]                # exactly one of R_mm, f_number (paper's scale) or r_px
    R_mm = 1.98

    [object]
    depth_mm = 500.0         # the depth the design is made for

    [schedule]
    kind = "parabolic"       # Eq. 11; or "centres" with centres_mm = [[x, y], ...] (x right,
                             # y down, mm), or "bitmap" with masks = "lcos/" (a folder of
                             # images), "masks.npy" or "masks.npz" (relative to this file)

Only ``[lens] focus_distance_mm``, ``[opening]`` and ``[schedule] kind`` are required; every
other key defaults to the paper's prototype. :func:`resolve_design` also takes a preset name,
a capture (``capture.exr`` or its ``capture.json``, whose design it reproduces exactly,
bitmaps included), a ``psf.json`` and a legacy ``schedule.json``. Every error names the key
and the valid range.
"""

from __future__ import annotations

import json
import math
import os
import re
import stat
from pathlib import Path

import numpy as np

from ..errors import FileKeyError, ParameterError
from ..io.arrays import read_json
from ..io.outputs import atomic_save, check_writable, write_text
from ..io.toml_file import read_toml
from ..limits import note
from .camera import PRESETS, CameraDesign, preset
from .masks import read_mask_stack
from .schedule_file import apply_schedule, read_schedule

FORMAT = 1
"""The design file's format version (``format = 1``)."""

SCHEDULE_KINDS = ("parabolic", "centres", "bitmap")
"""What ``[schedule] kind`` may be."""

_TABLES = {  # table -> {key in the file: CameraDesign field}
    "sensor": {
        "width_px": "width_px",
        "height_px": "height_px",
        "pixel_pitch_mm": "pixel_pitch_mm",
        "fov_deg": "fov_deg",
        "preset": "sensor_preset",
    },
    "lens": {"R_max_mm": "R_max_mm", "F_min": "F_min", "focus_distance_mm": "focus_distance_mm"},
    "lcos": {"pitch_mm": "lcos_pitch_mm", "rate_fps": "lcos_rate_fps"},
    "exposure": {"exposure_ms": "exposure_ms", "n_patterns": "n_patterns"},
    "object": {"depth_mm": "object_depth_mm"},
}
_OPENING_KEYS = ("R_mm", "f_number", "r_px")


def _number(v, key: str, where: str, integer: bool = False):
    ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) and v > 0
    if integer:
        ok = ok and isinstance(v, int)
    if not ok:
        kind = "a positive integer" if integer else "a positive number"
        raise ParameterError(f"{where}: {key} must be {kind}, got {v!r}")
    return v


def design_from_dict(d: dict, where: str = "design", base_dir: Path | None = None):
    """The :class:`CameraDesign` a design file's tables describe (see the module).

    Parameters
    ----------
    d : dict
        The parsed file.
    where : str
        The file's name, for messages.
    base_dir : Path, optional
        What a bitmap schedule's ``masks`` path is relative to.

    Raises
    ------
    ParameterError
        An unknown table or key, a value out of range, or a schedule that does not fit.
    """
    if d.get("format", FORMAT) != FORMAT:
        raise ParameterError(f"{where}: format must be {FORMAT}, got {d.get('format')!r}")
    known = {"format", "name", "opening", "schedule", *_TABLES}
    unknown = sorted(set(d) - known)
    if unknown:
        raise ParameterError(f"{where}: unknown keys {unknown}; valid: {sorted(known)}")
    kw: dict = {"name": str(d.get("name", Path(where).stem))}
    for table, keys in _TABLES.items():
        kw.update(_table(d, table, keys, where))
    base = preset("prototype").with_(**{k: v for k, v in kw.items() if k != "focus_distance_mm"})
    base = base.with_(quoted_a_i_px_per_ms2=None, focus_distance_mm=_focus(d, where))
    schedule = _schedule(d.get("schedule"), base, where, base_dir or Path("."))
    cam = _with(base, schedule, where)
    cam = _with(cam, {"R_mm": _opening(d.get("opening"), cam, where)}, where)
    cam.check_lcos_rate()
    return cam


def _with(cam: CameraDesign, changes: dict, where: str) -> CameraDesign:
    try:
        return cam.with_(**changes)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None


def _table(d: dict, table: str, keys: dict, where: str) -> dict:
    t = d.get(table, {})
    if not isinstance(t, dict):
        raise ParameterError(f"{where}: [{table}] must be a table")
    unknown = sorted(set(t) - set(keys))
    if unknown:
        raise ParameterError(f"{where}: unknown keys in [{table}]: {unknown}; valid: {list(keys)}")
    out = {}
    for key, fieldname in keys.items():
        if key not in t:
            continue
        if key == "preset":
            out[fieldname] = _sensor_preset(t[key], where)
            continue
        integer = key in ("width_px", "height_px", "n_patterns")
        out[fieldname] = _number(t[key], f"[{table}] {key}", where, integer)
    return out


def _sensor_preset(name, where: str) -> str:
    """A preset's name or file; the sensor checks that it exists where it is used."""
    if not isinstance(name, str) or not name.strip():
        raise ParameterError(
            f"{where}: [sensor] preset must name a sensor preset (e.g. grasshopper-icx285) or "
            f"a .json/.toml preset file, got {name!r}"
        )
    return name


def _focus(d: dict, where: str) -> float:
    lens = d.get("lens", {})
    if "focus_distance_mm" not in lens:
        raise ParameterError(f"{where}: [lens] focus_distance_mm is required (mm)")
    return _number(lens["focus_distance_mm"], "[lens] focus_distance_mm", where)


def _opening(t, cam: CameraDesign, where: str) -> float:
    """R in mm from exactly one of R_mm, f_number (N_min R_max / R) or r_px (|beta| R)."""
    if cam.pattern_masks is not None:
        if t:
            raise ParameterError(
                f"{where}: a bitmap schedule's opening is its masks: leave out [opening] (R "
                f"is the radius of the patterns' mean open area, "
                f"{cam.pattern_masks.equivalent_radius_mm():.5g} mm)"
            )
        return cam.pattern_masks.equivalent_radius_mm()
    given = [k for k in _OPENING_KEYS if isinstance(t, dict) and k in t]
    if len(given) != 1 or set(t) - set(_OPENING_KEYS):
        raise ParameterError(
            f"{where}: [opening] must give exactly one of {', '.join(_OPENING_KEYS)}, got {t!r}"
        )
    key = given[0]
    v = _number(t[key], f"[opening] {key}", where)
    if key == "R_mm":
        return v
    if key == "f_number":
        return cam.R_max_mm * cam.F_min / v
    if cam.beta_px_per_mm == 0.0:
        raise ParameterError(
            f"{where}: [opening] r_px needs defocus at the object (focus_distance_mm != depth_mm)"
        )
    return v / abs(cam.beta_px_per_mm)


def _schedule(t, cam: CameraDesign, where: str, base_dir: Path) -> dict:
    if not isinstance(t, dict) or t.get("kind") not in SCHEDULE_KINDS:
        got = t.get("kind") if isinstance(t, dict) else t
        raise ParameterError(
            f"{where}: [schedule] kind must be one of {', '.join(SCHEDULE_KINDS)}, got {got!r}"
        )
    kind = t["kind"]
    allowed = {
        "parabolic": {"kind"},
        "centres": {"kind", "centres_mm"},
        "bitmap": {"kind", "masks"},
    }
    extra = sorted(set(t) - allowed[kind])
    if extra:
        raise ParameterError(f"{where}: [schedule] kind {kind!r} takes no {extra}")
    if kind == "parabolic":
        return {}
    if kind == "centres":
        c = t.get("centres_mm")
        ok = isinstance(c, list) and all(isinstance(p, list) and len(p) == 2 for p in c)
        if not ok or len(c) != cam.n_patterns:
            raise ParameterError(
                f"{where}: [schedule] centres_mm must be n_patterns = {cam.n_patterns} pairs "
                f"[x, y] (mm, x right, y down), got {c!r}"
            )
        return {"pattern_centres_mm": tuple(tuple(p) for p in c)}
    src = t.get("masks")
    if not isinstance(src, str) or not src:
        raise ParameterError(
            f"{where}: [schedule] masks must name a .npy stack, an image or a folder of images"
        )
    path = base_dir / src
    stack = read_mask_stack(path, cam.lcos_pitch_mm, str(src), "[schedule] masks")
    stack.check_open()  # as the file names the masks: the design would say pattern_masks
    return {"pattern_masks": stack, "n_patterns": stack.n_patterns}


def read_design(path) -> CameraDesign:
    """The design in a TOML design file (see the module).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "d.toml"
    >>> _ = p.write_text('[lens]\\nfocus_distance_mm = 751.6\\n[opening]\\nf_number = 9.85\\n'
    ...                  '[schedule]\\nkind = "parabolic"\\n')
    >>> d = read_design(p)
    >>> d.n_patterns, round(d.r_px, 2), d.schedule_kind
    (16, 2.0, 'parabolic')
    """
    path = Path(path)
    d = read_toml(path, "design file")
    try:
        cam = design_from_dict(d, str(path), path.parent)
    except FileKeyError:
        raise
    except ParameterError as exc:  # a file's keys, not the command line's flags of that name
        raise FileKeyError(str(exc)) from None
    _check_digest_comment(path, cam)
    return cam


_DIGEST_COMMENT = re.compile(r"^# digest ([0-9a-f]{16});", re.MULTILINE)
_NOTED: set = set()


def _check_digest_comment(path: Path, cam: CameraDesign) -> None:
    """A note when the digest ``pacam design`` wrote in the file's header is not the camera's
    any more: the file was edited by hand (the camera is read as it now is)."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        head = fh.read(4096)
    m = _DIGEST_COMMENT.search(head)
    said = (str(path.resolve()), cam.digest())
    if m and m.group(1) != cam.digest() and said not in _NOTED:
        _NOTED.add(said)  # a command reads its design more than once: said once
        note(
            f"{path} was edited after pacam design wrote it: its camera's digest is now "
            f"{cam.digest()} (the header says {m.group(1)}); captures and kernels record the "
            "new one. Writing the design again (write_design) renews the header"
        )


def design_to_dict(cam: CameraDesign, masks_name: str | None = None) -> dict:
    """The design file's tables for ``cam`` (its opening as R_mm); a bitmap schedule names
    ``masks_name``, where :func:`write_design` saves the stack."""
    d: dict = {"format": FORMAT, "name": cam.name}
    for table, keys in _TABLES.items():
        d[table] = {k: getattr(cam, f) for k, f in keys.items() if getattr(cam, f) is not None}
    if cam.pattern_masks is None:
        d["opening"] = {"R_mm": cam.R_mm}
    sched: dict = {"kind": cam.schedule_kind}
    if cam.pattern_centres_mm is not None:
        sched["centres_mm"] = [list(c) for c in cam.pattern_centres_mm]
    if cam.pattern_masks is not None:
        sched["masks"] = masks_name
    d["schedule"] = sched
    return d


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, float):
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")


def as_read_back(cam: CameraDesign) -> CameraDesign:
    """``cam`` as its design file reads back: a bitmap schedule's opening R is its masks'
    equivalent radius (:func:`_opening`), whatever R the camera it was made from kept, so the
    header's digest is the read camera's (else every read said the file was edited)."""
    if cam.pattern_masks is None:
        return cam
    R = cam.pattern_masks.equivalent_radius_mm()
    return cam if cam.R_mm == R else cam.with_(R_mm=R)


def design_toml(cam: CameraDesign, masks_name: str | None = None) -> str:
    """The text of a design file for ``cam`` (exact: floats are written with repr); the
    header's digest is that of the camera the file reads back as (:func:`as_read_back`)."""
    cam = as_read_back(cam)
    d = design_to_dict(cam, masks_name)
    fig = cam.summary()
    a_i = fig["a_i_px_per_ms2"]
    how = "Eq. 18" if not cam.designed else "fitted to the schedule"
    motion = "no parabola fits" if a_i is None else f"a_i = {a_i:.4g} px/ms^2 ({how})"
    lines = [
        "# pacam camera design (pacam design --write): lengths mm, times ms, angles deg, px.",
        f"# digest {cam.digest()}; r = {cam.r_px:.4g} px, {motion}, {cam.n_patterns} "
        f"patterns in {cam.exposure_ms:g} ms",
        f"format = {FORMAT}",
        f"name = {_toml_value(d['name'])}",
    ]
    for table in (*_TABLES, "opening", "schedule"):
        if table in d:
            lines += ["", f"[{table}]"]
            lines += [f"{k} = {_toml_value(v)}" for k, v in d[table].items()]
    return "\n".join(lines) + "\n"


def write_design(path, cam: CameraDesign, force: bool = False) -> list[Path]:
    """Write ``cam`` as a design file (and, for a bitmap schedule, ``<stem>.masks.npz``
    beside it); atomic, and refused over an existing file unless ``force``.

    Returns
    -------
    list of Path
        The files written.
    """

    path = check_writable(Path(path), force, "design file")
    written = []
    masks_name = None
    if cam.pattern_masks is not None:  # compressed, 8-bit where exact: a few kB per pattern
        masks_name = f"{path.stem}.masks.npz"
        stack = cam.pattern_masks.compact_array()
        save = lambda tmp: np.savez_compressed(tmp, masks=stack)  # noqa: E731
        written.append(atomic_save(path.parent / masks_name, save, force))
    write_text(path, design_toml(cam, masks_name), force)
    return [path, *written]


def resolve_design(source, **overrides) -> CameraDesign:
    """A camera design from any source a command may name.

    Parameters
    ----------
    source : str or path-like
        A preset name (``prototype``); a design file (``.toml``); a capture (``capture.exr``
        or its ``capture.json``: the coded design it was made with, exactly); a ``psf.json``
        (the camera its kernel was made for); or a legacy ``schedule.json`` of
        ``pacam optimize`` (applied to the prototype).
    **overrides
        CameraDesign fields to change afterwards (e.g. ``object_depth_mm``).

    Returns
    -------
    CameraDesign
    """
    s = os.fspath(source)
    path = Path(s)
    if path.suffix.lower() == ".toml":
        cam = read_design(path)
    elif path.suffix.lower() in (".exr", ".json"):
        cam = _design_from_json(path)
    elif s not in PRESETS and os.path.lexists(s):  # a path, not a preset's name
        raise ParameterError(
            f"`design` {s!r} is not a design file ({_what_is(path)}); give a design file "
            "(.toml), a capture (.exr or .json), a psf.json or schedule.json, or a preset: "
            f"{', '.join(sorted(PRESETS))}"
        )
    else:
        cam = preset(s)
    return cam.with_(**overrides) if overrides else cam


def _what_is(path: Path) -> str:
    """What an existing path that no design reader takes is, for the message."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return "a link to nothing"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISREG(mode):
        return "a file not named .toml, .json or .exr"
    return "a device, a pipe or a socket"


def _design_from_json(path: Path) -> CameraDesign:
    """The design in a capture's, a PSF's or a legacy schedule's JSON."""
    jpath = path.with_suffix(".json") if path.suffix.lower() == ".exr" else path

    d = read_json(jpath, "design source")
    if not isinstance(d, dict):
        raise ParameterError(f"{jpath}: expected a JSON object")
    for key in ("design", "camera"):  # a capture's coded design, else the camera of a PSF
        if isinstance(d.get(key), dict):
            return CameraDesign.from_inputs(d[key])
    if "centres_mm" in d:
        sched = read_schedule(jpath)
        base = preset("prototype", object_depth_mm=sched.get("object_depth_mm", 500.0))
        return apply_schedule(base, sched, str(jpath))
    raise ParameterError(
        f"{jpath} holds no camera design: expected a pacam capture.json, psf.json or schedule.json"
    )
