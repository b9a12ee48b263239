"""Aperture motion over the exposure (paper Section 2.3, Eqs. 11 and 15-18).

Time t runs over [-T, T] ms (exposure 2T), t = 0 at mid-exposure. The opening of radius R moves
along the lens x axis as X_a(t) = a_a t^2/2 - (R_max - R): from one edge of the clear aperture at
t = -T to the other at t = 0 and back, travelling Delta X_a = 2 (R_max - R) (Eq. 15) each way.

The LCoS shows ``n`` discrete patterns: pattern k is on during
[-T + k 2T/n, -T + (k+1) 2T/n) and its centre is X_a at that window's mid-time.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError, check_positive
from .paper import N_PATTERNS

RASKAR_2006_CODE = "1010000111000001010000110011110111010111001001100111"
"""The 52-chop fluttered-shutter code of Raskar, Agrawal and Tumblin (SIGGRAPH 2006)."""


def _check_radii(R_max_mm: float, R_mm: float) -> tuple[float, float]:
    R_max = check_positive("R_max_mm", R_max_mm, "mm")
    R = check_positive("R_mm", R_mm, "mm")
    if R > R_max:
        raise ParameterError(
            f"R_mm must be in (0, R_max_mm = {R_max:g}] mm (opening inside the lens), got {R_mm!r}"
        )
    return R_max, R


def aperture_travel_mm(R_max_mm: float, R_mm: float) -> float:
    """Delta X_a = 2 (R_max - R) (Eq. 15), mm."""
    R_max, R = _check_radii(R_max_mm, R_mm)
    return 2.0 * (R_max - R)


def aperture_acceleration(R_max_mm: float, R_mm: float, T_ms: float) -> float:
    """a_a = 2 Delta X_a / T^2 = 4 (R_max - R) / T^2 (Eqs. 16-17), mm/ms^2."""
    T = check_positive("T_ms", T_ms, "ms")
    return 2.0 * aperture_travel_mm(R_max_mm, R_mm) / T**2


def image_acceleration(beta_px: float, R_max_mm: float, R_mm: float, T_ms: float) -> float:
    """a_i = beta a_a = 4 beta (R_max - R) / T^2 (Eqs. 10, 18), px/ms^2 (signed like beta)."""
    return beta_px * aperture_acceleration(R_max_mm, R_mm, T_ms)


def velocity_range(a_i: float, T_ms: float) -> float:
    """Half-width of the motion-invariant speed range, |s| <= |a_i| T, px/ms."""
    return abs(a_i) * check_positive("T_ms", T_ms, "ms")


def aperture_centre_mm(t_ms, R_max_mm: float, R_mm: float, T_ms: float) -> np.ndarray:
    """Continuous centre X_a(t) of the opening (Eq. 11 shifted into the lens), mm."""
    R_max, R = _check_radii(R_max_mm, R_mm)
    a_a = aperture_acceleration(R_max, R, T_ms)
    return 0.5 * a_a * np.asarray(t_ms, dtype=float) ** 2 - (R_max - R)


def max_patterns(exposure_ms: float, rate_fps: float) -> int:
    """The most patterns an LCoS showing ``rate_fps`` per second shows in ``exposure_ms``
    (Table 1: 365 per s, so 16 in the paper's 45 ms)."""
    return int(math.floor(rate_fps * exposure_ms / 1000.0 + 1e-9))


MAX_PATTERNS = 4096
"""The most patterns a schedule may have: 11x what the fastest LCoS we know of shows in 45 ms
(a ferroelectric display at ~10^4 fps holds ~450), and what keeps a design's per-pattern
tables, records and reports bounded (a 10^6-pattern design printed a million lines)."""


def check_n_patterns(n: int) -> int:
    if int(n) != n or n < 1:
        raise ParameterError(f"n_patterns must be an integer >= 1, got {n!r}")
    return int(n)


def check_design_patterns(n: int) -> int:
    """A camera's pattern count: :func:`check_n_patterns`, and at most :data:`MAX_PATTERNS`."""
    n = check_n_patterns(n)
    if n > MAX_PATTERNS:
        raise ParameterError(
            f"n_patterns must be at most {MAX_PATTERNS} (11x the patterns the fastest known "
            f"LCoS shows in one 45 ms exposure), got {n}"
        )
    return n


def pattern_edges_ms(T_ms: float, n: int) -> np.ndarray:
    """The n + 1 window boundaries -T, ..., T, ms."""
    return np.linspace(-check_positive("T_ms", T_ms, "ms"), T_ms, check_n_patterns(n) + 1)


def pattern_mid_times_ms(T_ms: float, n: int) -> np.ndarray:
    """Mid-time of each pattern window, ms."""
    e = pattern_edges_ms(T_ms, n)
    return 0.5 * (e[:-1] + e[1:])


def pattern_index(t_ms, T_ms: float, n: int) -> np.ndarray:
    """Index of the pattern shown at time t (t = T belongs to the last pattern)."""
    T = check_positive("T_ms", T_ms, "ms")
    n = check_n_patterns(n)
    k = np.floor((np.asarray(t_ms, dtype=float) + T) * (n / (2.0 * T)))
    return np.clip(k, 0, n - 1).astype(int)


def pattern_centres_mm(
    R_max_mm: float, R_mm: float, T_ms: float, n: int = N_PATTERNS
) -> np.ndarray:
    """Centre of each of the n patterns: X_a at the window's mid-time, mm."""
    return aperture_centre_mm(pattern_mid_times_ms(T_ms, n), R_max_mm, R_mm, T_ms)


def flutter_code(code: str = RASKAR_2006_CODE) -> np.ndarray:
    """A shutter code as a 0/1 float array; it must open at least once."""
    if not code or set(code) - {"0", "1"}:
        raise ParameterError(f"flutter code must be a non-empty string of 0/1, got {code!r}")
    bits = np.array([c == "1" for c in code], dtype=float)
    if bits.sum() == 0:
        raise ParameterError("flutter code must open the shutter at least once (all zeros)")
    return bits
