"""Exact pixel coverage of a uniform disc: the static defocus PSF psi (Eq. 13).

The area of a disc of radius r intersected with an axis-aligned rectangle is a signed sum of four
"quadrant" areas A(x, y) = |disc ∩ {X <= x, Y <= y}|, each in closed form from
G(u) = (u sqrt(r^2 - u^2) + r^2 asin(u / r)) / 2, the integral of a half-chord. No sampling,
so psi is exact for any r and centre, and tends to a delta as r -> 0.
"""

from __future__ import annotations

import numpy as np


def _G(u: np.ndarray, r: float) -> np.ndarray:
    """Integral of sqrt(r^2 - u^2) du from 0 to u (|u| <= r)."""
    return 0.5 * (u * np.sqrt(np.maximum(r * r - u * u, 0.0)) + r * r * np.arcsin(u / r))


def quadrant_area(x: np.ndarray, y: np.ndarray, r: float) -> np.ndarray:
    """Area of {X <= x, Y <= y, X^2 + Y^2 <= r^2} for a disc centred at the origin."""
    x = np.clip(x, -r, r)
    y = np.clip(y, -r, r)
    w = np.sqrt(np.maximum(r * r - y * y, 0.0))  # half-width of the chord at height y
    xm = np.clip(x, -w, w)
    middle = y * (xm + w) + _G(xm, r) - _G(-w, r)  # |u| <= w: chord from -h(u) to y
    sides = 2.0 * (_G(np.clip(x, -r, -w), r) - _G(-r, r)) + 2.0 * (
        _G(np.clip(x, w, r), r) - _G(w, r)
    )
    return middle + np.where(y >= 0.0, sides, 0.0)


def row_coverage(centres_x: np.ndarray, r: float, x_edges: np.ndarray, y0: float, y1: float):
    """Area of each disc (centre (cx, 0)) inside each pixel [x_i, x_i+1) x [y0, y1).

    Returns an array of shape (len(centres_x), len(x_edges) - 1), in px^2.
    """
    dx = x_edges[None, :] - np.asarray(centres_x, dtype=float)[:, None]
    upper = quadrant_area(dx, np.full_like(dx, y1), r)
    lower = quadrant_area(dx, np.full_like(dx, y0), r)
    cum = upper - lower  # area with X <= edge inside the row
    return np.maximum(np.diff(cum, axis=1), 0.0)


def disc_coverage(r: float, shape: tuple[int, int], centre=(0.0, 0.0)) -> np.ndarray:
    """Exact area of a disc of radius r px in each pixel of a (h, w) grid centred at 0, px^2.

    Pixel (i, j) spans [j - w//2 - 1/2, j - w//2 + 1/2) in x, likewise in y. r = 0 puts all the
    (unit) area in the pixel that contains the centre.
    """
    h, w = shape
    xe = np.arange(w + 1) - w // 2 - 0.5 - centre[0]
    ye = np.arange(h + 1) - h // 2 - 0.5 - centre[1]
    out = np.zeros((h, w))
    if r == 0.0:
        j = np.searchsorted(xe, 0.0, side="right") - 1
        i = np.searchsorted(ye, 0.0, side="right") - 1
        if 0 <= i < h and 0 <= j < w:
            out[i, j] = 1.0
        return out
    for i in range(h):
        if ye[i] < r and ye[i + 1] > -r:
            out[i] = row_coverage(np.zeros(1), r, xe, ye[i], ye[i + 1])[0]
    return out
