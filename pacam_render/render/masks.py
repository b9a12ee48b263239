"""LCoS aperture bitmaps for the plugin: importance-sampling tables of a mask stack.

What a mask is, its orientation, and how stacks are loaded and checked:
:mod:`pacam_render.model.masks` (re-exported here).

Importance sampling: each pattern is stored as runs of equal non-zero transmittance along its
rows, in a cumulative table (CDF) with a guide table (Chen and Asau's cut-point method) that
narrows the binary search to a run or two. A sample picks a run with probability tau x length /
sum and a uniform point in it: a point lands in pixel j with probability tau_j / sum(tau) and
uniformly inside it, so its area density on the aperture plane is tau / (sum(tau) pitch^2), and
the estimator weight is the open area sum(tau) * pitch^2 (mm^2), whatever the mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import check_positive
from ..model.masks import (  # noqa: F401  (re-exported: the plugin's callers import them here)
    DISPLAY_SHAPE,
    check_masks,
    disc_mask,
    disc_masks,
    load_masks,
    pixel_centres_mm,
)
from ..model.optics import LCOS_PITCH_MM


@dataclass(frozen=True)
class MaskTables:
    """Importance-sampling tables of a mask stack, concatenated over the patterns.

    A mask is stored as *runs*: maximal horizontal stretches of pixels of one row with the same
    non-zero transmittance (a binary disc of radius 150 px is ~300 runs, not 70 000 pixels, so
    the tables stay in the CPU cache). Per run: ``x_hi_mm`` (its edge at the largest x: x falls
    with the column), ``y_mm`` (its row's centre), ``span_mm`` (length x pitch) and ``cdf``
    (inclusive cumulative probability within its pattern, tau x length / sum; the pattern's
    last entry exactly 1). Per pattern: ``start``, ``count`` (its slice of the run arrays),
    ``guide_start`` (its slice of ``guide``, ``count + 1`` entries) and ``area_mm2`` (the open
    area sum(tau) pitch^2). ``guide[g + i]`` bounds from below the index of the first run whose
    ``cdf`` exceeds u for every u in [i/count, (i+1)/count), and ``guide[g + i + 1]`` from
    above.
    """

    x_hi_mm: np.ndarray
    y_mm: np.ndarray
    span_mm: np.ndarray
    cdf: np.ndarray
    start: np.ndarray
    count: np.ndarray
    guide: np.ndarray
    guide_start: np.ndarray
    area_mm2: np.ndarray
    pitch_mm: float

    @property
    def n_patterns(self) -> int:
        return len(self.count)


def _runs(m: np.ndarray):
    """Row, first column, length and value of each run of equal non-zero values."""
    h, w = m.shape
    first = np.ones((h, w), dtype=bool)
    first[:, 1:] = m[:, 1:] != m[:, :-1]
    rows, cols = np.nonzero(first)  # row-major; every row starts a run at column 0
    flat = rows * w + cols
    length = np.append(flat[1:], h * w) - flat  # runs end at the next start, or the row's end
    value = m[rows, cols]
    keep = value > 0
    return rows[keep], cols[keep], length[keep], value[keep].astype(np.float64)


def build_tables(masks: np.ndarray, pitch_mm: float = LCOS_PITCH_MM) -> MaskTables:
    """Sampling tables for a checked ``(N, H, W)`` stack (see :class:`MaskTables`)."""
    pitch = check_positive("mask_pitch", pitch_mm, "mm")
    xc, yc = pixel_centres_mm(masks.shape[1:], pitch)
    x_hi, ys, spans, cdfs, guides = [], [], [], [], []
    start, count, gstart, area = [], [], [], []
    n_runs = n_guide = 0
    for m in masks:
        rows, cols, length, tau = _runs(m)
        mass = tau * length
        total = float(mass.sum())
        n = len(mass)
        start.append(n_runs)
        count.append(n)
        gstart.append(n_guide)
        area.append(total * pitch * pitch)
        if n == 0:  # closed pattern: a dummy guide entry keeps the offsets consistent
            guides.append(np.zeros(1, dtype=np.uint32))
            n_guide += 1
            continue
        cdf32 = (np.cumsum(mass) / total).astype(np.float32)
        cdf32[-1] = 1.0
        # guide[i]: first j with cdf32[j] > i/n (a hair lower, so float32 rounding of u*n in
        # the kernel can never start the search past the answer); guide[n] = n - 1.
        q = (np.arange(n + 1) / n) * (1.0 - 1e-6)
        g = np.searchsorted(cdf32, q.astype(np.float32), side="right")
        g = np.minimum(g, n - 1).astype(np.uint32)
        g[-1] = n - 1
        x_hi.append((xc[cols] + 0.5 * pitch).astype(np.float32))
        ys.append(yc[rows].astype(np.float32))
        spans.append((length * pitch).astype(np.float32))
        cdfs.append(cdf32)
        guides.append(g)
        n_runs += n
        n_guide += n + 1
    cat = np.concatenate
    empty = np.zeros(0, np.float32)
    return MaskTables(
        x_hi_mm=cat(x_hi) if x_hi else empty,
        y_mm=cat(ys) if ys else empty,
        span_mm=cat(spans) if spans else empty,
        cdf=cat(cdfs) if cdfs else empty,
        start=np.asarray(start, np.uint32),
        count=np.asarray(count, np.uint32),
        guide=cat(guides).astype(np.uint32),
        guide_start=np.asarray(gstart, np.uint32),
        area_mm2=np.asarray(area, np.float64),
        pitch_mm=pitch,
    )


def sample_tables_numpy(tables: MaskTables, k, u1, u2) -> tuple[np.ndarray, np.ndarray]:
    """Reference (numpy, float64) sampler: aperture points (mm) for pattern(s) k.

    Picks run j of pattern k with probability tau_j length_j / sum by inverting the CDF with
    ``np.searchsorted``, then a uniform point in the run (u1's residual across the run's CDF
    step along x, u2 across the row), which is what the kernel does with its guided search.
    """
    k = np.asarray(k, dtype=np.int64)
    u1 = np.asarray(u1, dtype=np.float64)
    u2 = np.asarray(u2, dtype=np.float64)
    k, u1, u2 = np.broadcast_arrays(k, u1, u2)
    x = np.empty(u1.shape)
    y = np.empty(u1.shape)
    for kk in np.unique(k):
        sel = k == kk
        s, n = int(tables.start[kk]), int(tables.count[kk])
        if n == 0:
            x[sel] = y[sel] = np.nan
            continue
        cdf = tables.cdf[s : s + n].astype(np.float64)
        j = np.minimum(np.searchsorted(cdf, u1[sel], side="right"), n - 1)
        lo = np.where(j > 0, cdf[np.maximum(j - 1, 0)], 0.0)
        r = np.clip((u1[sel] - lo) / np.maximum(cdf[j] - lo, 1e-30), 0.0, 1.0)
        x[sel] = tables.x_hi_mm[s + j] - r * tables.span_mm[s + j]
        y[sel] = tables.y_mm[s + j] + (u2[sel] - 0.5) * tables.pitch_mm
    return x, y
