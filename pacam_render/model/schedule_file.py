"""A designed aperture schedule on disk: ``schedule.json`` (written by ``pacam optimize``).

Keys read (every other key is kept as information):

- ``centres_mm``: n pairs (x, y), mm: each pattern's opening centre, x to the image's right and
  y downwards, as on the LCoS bitmaps;
- ``radius_mm`` (one value), or ``radii_mm`` (n equal values): the opening's radius;
- ``focus_distance_mm``, ``n_patterns``;
- optional ``exposure_ms`` and ``object_depth_mm`` (the design's; a capture may override the
  depth).

Every error names the key and the valid range.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from ..io.arrays import read_json
from . import paper
from . import schedule as sch
from .camera import CameraDesign


def max_patterns(exposure_ms: float, rate_fps: float = paper.LCOS_RATE_FPS) -> int:
    """The most patterns the LCoS can show in one exposure (Table 1's 365 fps by default)."""
    return sch.max_patterns(exposure_ms, rate_fps)


def check_pattern_count(
    n, exposure_ms: float, flag: str = "n_patterns", rate_fps: float = paper.LCOS_RATE_FPS
) -> int:
    """``n`` if 2 <= n <= what the LCoS shows in ``exposure_ms``, else ParameterError."""
    top = max_patterns(exposure_ms, rate_fps)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 2 <= n <= top:
        raise ParameterError(
            f"{flag} must be an integer in [2, {top}]: a moving opening needs 2 patterns, and "
            f"the LCoS shows at most {rate_fps:g} per second ({top} in "
            f"{exposure_ms:g} ms), got {n!r}"
        )
    return int(n)


def _number(d: dict, key: str, where: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise ParameterError(f"{where}: {key!r} must be a positive number, got {v!r}")
    return float(v)


def _radius(d: dict, n: int, where: str) -> float:
    if "radius_mm" in d:
        return _number(d, "radius_mm", where)
    radii = d.get("radii_mm")
    if not isinstance(radii, list) or len(radii) != n:
        raise ParameterError(f"{where}: needs 'radius_mm' (one value) or 'radii_mm' ({n} values)")
    r = [_number({"radii_mm": v}, "radii_mm", where) for v in radii]
    if max(r) - min(r) > 1e-9 * max(r):
        raise ParameterError(
            f"{where}: 'radii_mm' must all be equal (openings of different radii are not "
            f"rendered yet), got {min(r):g} to {max(r):g} mm"
        )
    return r[0]


def _centres(d: dict, n: int, where: str) -> tuple[tuple[float, float], ...]:
    c = d.get("centres_mm")
    ok = isinstance(c, list) and len(c) == n
    ok = ok and all(isinstance(p, list) and len(p) == 2 for p in c)
    ok = ok and all(isinstance(v, (int, float)) and math.isfinite(v) for p in c for v in p)
    if not ok:
        raise ParameterError(f"{where}: 'centres_mm' must be {n} pairs [x, y] of finite mm")
    return tuple((float(x), float(y)) for x, y in c)


def read_schedule(path) -> dict:
    """The checked contents of a ``schedule.json``.

    Returns
    -------
    dict
        The file's object, with ``centres_mm`` as a tuple of pairs and ``radius_mm`` set.

    Raises
    ------
    ParameterError
        Unreadable file or JSON, a file too large or nested too deep to parse (read by
        :func:`~pacam_render.io.arrays.read_json`, bounded as records are), or a key missing or
        out of range (the message names it).
    """
    where = str(path)
    d = read_json(path, "`schedule`")
    if not isinstance(d, dict):
        raise ParameterError(f"{where}: expected a JSON object, got {type(d).__name__}")
    exposure = _number(d, "exposure_ms", where) if "exposure_ms" in d else paper.EXPOSURE_MS
    n = check_pattern_count(d.get("n_patterns"), exposure, f"{where}: 'n_patterns'")
    out = dict(d)
    out.update(
        n_patterns=n,
        exposure_ms=exposure,
        centres_mm=_centres(d, n, where),
        radius_mm=_radius(d, n, where),
        focus_distance_mm=_number(d, "focus_distance_mm", where),
    )
    if "object_depth_mm" in d:
        out["object_depth_mm"] = _number(d, "object_depth_mm", where)
    return out


def apply_schedule(base: CameraDesign, sched: dict, where: str = "schedule") -> CameraDesign:
    """``base`` showing the schedule (:func:`read_schedule`'s dict): its opening, focus,
    exposure, pattern count and centres. The depth stays the base's.

    Raises
    ------
    ParameterError
        An opening outside the lens or smaller than an LCoS pixel, named by its key.
    """
    try:
        return base.with_(
            R_mm=sched["radius_mm"],
            focus_distance_mm=sched["focus_distance_mm"],
            exposure_ms=sched["exposure_ms"],
            n_patterns=sched["n_patterns"],
            pattern_centres_mm=sched["centres_mm"],
            name=f"designed schedule ({where})",
            quoted_a_i_px_per_ms2=None,
        )
    except ParameterError as exc:
        msg = str(exc).replace("pattern_centres_mm", "centres_mm").replace("R_mm", "radius_mm")
        raise ParameterError(f"{where}: {msg}") from None
