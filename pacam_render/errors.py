"""The one exception type users see for bad input.

Every check raises :class:`ParameterError` with the parameter's name and its valid range, so the
CLI can print one clear line instead of a traceback. A message names parameters, never flags: a
name with an underscore bare (``max_step_px``), a one-word name in backticks (``"`spp`"``,
``"`force=True`"``), so that prose such as "64 spp" stays prose; the CLI alone shows them as its
flags (:data:`pacam_render.cli.common.FLAGS`).
"""

from __future__ import annotations

import math


class ParameterError(ValueError):
    """A parameter is outside its valid range; the message names both."""


class FileKeyError(ParameterError):
    """A bad key or value in an input file (a study's TOML): the message names the file's
    keys, which the CLI shows as they are (not as the flags of the same name)."""


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as float, or raise if it is NaN or infinite."""
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    return v


def check_positive(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as float, or raise unless it is finite and > 0."""
    v = check_finite(name, value)
    if v <= 0:
        raise ParameterError(f"{name} must be > 0{(' ' + unit) if unit else ''}, got {value!r}")
    return v


def check_range(name: str, value: float, lo: float, hi: float, unit: str = "") -> float:
    """Return ``value`` as float, or raise unless lo <= value <= hi."""
    v = check_finite(name, value)
    if not lo <= v <= hi:
        u = f" {unit}" if unit else ""
        raise ParameterError(f"{name} must be in [{lo:g}, {hi:g}]{u}, got {value!r}")
    return v


def check_integer(name: str, value: object, lo: int, hi: int | None) -> int:
    """Return ``value`` as int, or raise unless it is an integer (not a bool) in lo..hi
    (``hi`` None: no upper bound)."""
    import numpy as np

    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    rng = f"{lo}..{hi}" if hi is not None else f">= {lo}"
    if not ok or value < lo or (hi is not None and value > hi):
        raise ParameterError(f"{name} must be an integer {rng}, got {value!r}")
    return int(value)


def did_you_mean(word: object, valid, cutoff: float = 0.6) -> str:
    """`` (did you mean 'x'?)`` for the entry of ``valid`` nearest ``word``, or ``""``."""
    import difflib

    close = difflib.get_close_matches(str(word), list(valid), n=1, cutoff=cutoff)
    return f" (did you mean {close[0]!r}?)" if close else ""
