"""LCoS aperture bitmaps: load, check, rasterise, and importance-sample them.

A *mask* is one greyscale image of the programmable aperture's LCoS display (the prototype's is
1280x1024 pixels at a 13.62 um pitch); its grey level is the transmittance, 0 (black, closed)
to 1 (white, open). A *mask stack* has shape ``(N, H, W)``: pattern ``k`` is shown during the
k-th of N equal shares of the exposure (see :mod:`pacam_render.model.schedule`).

Orientation (the one convention every function here and the camera plugin share): a mask is
the display as seen from the sensor looking into the scene, in the same orientation as the
rendered image. Column ``j`` grows to the image's right, row ``i`` grows downwards, and the
display centre is on the optical axis. In the camera's local frame (Mitsuba: +z forward, +y up,
+x to the image's *left*), pixel (i, j) of an ``H x W`` mask has its centre at

    x_mm = -(j + 0.5 - W/2) * pitch,        y_mm = (H/2 - i - 0.5) * pitch.

So a disc at aperture coordinate ``(c, 0)`` with c > 0 appears in the left half of the mask.

Importance sampling: each pattern is stored as runs of equal non-zero transmittance along its
rows, in a cumulative table (CDF) with a guide table (Chen and Asau's cut-point method) that
narrows the binary search to a run or two. A sample picks a run with probability tau x length /
sum and a uniform point in it: a point lands in pixel j with probability tau_j / sum(tau) and
uniformly inside it, so its area density on the aperture plane is tau / (sum(tau) pitch^2), and
the estimator weight is the open area sum(tau) * pitch^2 (mm^2), whatever the mask.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_positive
from ..model.optics import LCOS_PITCH_MM

DISPLAY_SHAPE = (1024, 1280)
"""Rows, columns of the prototype's LCoS display (SXGA, 1280x1024)."""


def pixel_centres_mm(shape: tuple[int, int], pitch_mm: float = LCOS_PITCH_MM):
    """Aperture-plane coordinates (mm) of the pixel centres: x per column, y per row."""
    h, w = (int(s) for s in shape)
    pitch = check_positive("mask_pitch", pitch_mm, "mm")
    x = -(np.arange(w) + 0.5 - w / 2.0) * pitch
    y = (h / 2.0 - np.arange(h) - 0.5) * pitch
    return x, y


def disc_mask(
    centre_mm: Sequence[float] = (0.0, 0.0),
    radius_mm: float = 1.0,
    shape: tuple[int, int] = DISPLAY_SHAPE,
    pitch_mm: float = LCOS_PITCH_MM,
    supersample: int = 1,
) -> np.ndarray:
    """A disc of transmittance 1 on the display, float32 ``(H, W)``.

    ``supersample = 1`` opens the pixels whose centre lies inside the disc (a binary mask, what
    an LCoS shows); ``supersample = s > 1`` gives each pixel the fraction of its s x s
    sub-pixel centres inside the disc (an anti-aliased grey mask, closer to the ideal disc).
    """
    r = check_positive("radius_mm", radius_mm, "mm")
    s = int(supersample)
    if s < 1:
        raise ParameterError(f"supersample must be an integer >= 1, got {supersample!r}")
    cx, cy = (float(v) for v in centre_mm)
    h, w = (int(v) for v in shape)
    pitch = check_positive("mask_pitch", pitch_mm, "mm")
    out = np.zeros((h, w), np.float32)
    x, y = pixel_centres_mm((h, w), pitch)
    # only the pixels whose square can touch the disc
    cols = np.flatnonzero(np.abs(x - cx) <= r + pitch)
    rows = np.flatnonzero(np.abs(y - cy) <= r + pitch)
    if cols.size == 0 or rows.size == 0:
        return out
    off = ((np.arange(s) + 0.5) / s - 0.5) * pitch  # sub-pixel offsets, centred in the pixel
    xs = (x[cols, None] - off[None, :]).reshape(-1)  # x falls with the column
    ys = (y[rows, None] - off[None, :]).reshape(-1)
    inside = ((xs[None, :] - cx) ** 2 + (ys[:, None] - cy) ** 2) <= r * r
    cover = inside.reshape(rows.size, s, cols.size, s).mean(axis=(1, 3))
    out[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1] = cover
    return out


def disc_masks(
    centres_mm,
    radius_mm: float,
    shape: tuple[int, int] = DISPLAY_SHAPE,
    pitch_mm: float = LCOS_PITCH_MM,
    supersample: int = 1,
) -> np.ndarray:
    """One :func:`disc_mask` per centre: a ``(N, H, W)`` stack (e.g. a parabolic schedule).

    ``centres_mm`` is ``(N,)`` (x only, y = 0) or ``(N, 2)``.
    """
    c = np.asarray(centres_mm, dtype=float)
    if c.ndim == 1:
        c = np.stack([c, np.zeros_like(c)], axis=1)
    return np.stack([disc_mask(ci, radius_mm, shape, pitch_mm, supersample) for ci in c])


def _as_array(source) -> np.ndarray:
    """ndarray from an array-like, a Dr.Jit tensor/array or a Mitsuba Bitmap."""
    if isinstance(source, np.ndarray):
        return source
    cls = type(source).__name__
    if cls == "Bitmap":
        arr = np.array(source)
        if arr.ndim == 3:
            if arr.shape[2] in (2, 4):  # drop alpha
                arr = arr[..., :-1]
            if arr.shape[2] == 3:  # Rec. 709 luminance of the code values
                arr = arr @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float64)
            else:
                arr = arr[..., 0]
        return arr
    return np.array(source)


def _normalise(arr: np.ndarray, name: str) -> np.ndarray:
    """Transmittance in [0, 1] as float32; 8/16-bit integers are code values."""
    if arr.size == 0:
        raise ParameterError(f"{name}: empty mask (shape {arr.shape})")
    if arr.dtype == np.bool_:
        return arr.astype(np.float32)
    if arr.dtype in (np.uint8, np.uint16):  # image code values
        return (arr.astype(np.float64) / np.iinfo(arr.dtype).max).astype(np.float32)
    arr = arr.astype(np.float64)
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name}: transmittance must be finite (found NaN or inf)")
    lo, hi = float(arr.min()), float(arr.max())
    if lo < 0.0 or hi > 1.0:
        raise ParameterError(f"{name}: transmittance must be in [0, 1], got [{lo:g}, {hi:g}]")
    return arr.astype(np.float32)


def _load_file(path: str) -> np.ndarray:
    if not os.path.isfile(path):
        raise ParameterError(f"mask_file: no such file {path!r}")
    if path.lower().endswith(".npy"):
        return np.load(path)
    import mitsuba as mi

    return _as_array(mi.Bitmap(path))


def load_masks(source, name: str = "masks") -> np.ndarray:
    """A float32 ``(N, H, W)`` transmittance stack from any supported source.

    ``source`` may be an array-like ``(H, W)`` or ``(N, H, W)`` (transmittance in [0, 1]; 8- and
    16-bit arrays and images are grey levels, read as level / 255 or level / 65535 with no gamma
    decoding), a Dr.Jit tensor, a Mitsuba ``Bitmap``, a sequence of any of these, a
    path to a ``.npy`` stack or an image, or a comma-separated string of such paths.
    """
    if isinstance(source, str):
        paths = [p.strip() for p in source.split(",") if p.strip()]
        if not paths:
            raise ParameterError(f"{name}: empty file list")
        parts = [_load_file(p) for p in paths]
    elif isinstance(source, (list, tuple)):
        if len(source) == 0:
            raise ParameterError(f"{name}: empty list of masks")
        parts = [_as_array(s) for s in source]
    else:
        parts = [_as_array(source)]
    stack = []
    for p in parts:
        a = _normalise(np.asarray(p), name)
        if a.ndim == 2:
            a = a[None]
        if a.ndim != 3:
            raise ParameterError(f"{name}: expected (H, W) or (N, H, W) masks, got shape {a.shape}")
        stack.append(a)
    shapes = {a.shape[1:] for a in stack}
    if len(shapes) != 1:
        raise ParameterError(f"{name}: all masks must have the same size, got {sorted(shapes)}")
    out = np.concatenate(stack, axis=0)
    if out.size == 0:
        raise ParameterError(f"{name}: empty mask (shape {out.shape})")
    return out


def check_masks(masks: np.ndarray, lens_radius_mm: float, pitch_mm: float = LCOS_PITCH_MM):
    """Raise unless some pattern transmits light and no open pixel lies outside the lens.

    A pixel is outside the lens when its centre is farther than ``lens_radius_mm`` from the
    optical axis. Individual all-black patterns are allowed (the aperture is closed then, like
    a shutter); a stack that is black everywhere is not.
    """
    R_max = check_positive("lens_radius", lens_radius_mm, "mm")
    if masks.ndim != 3 or masks.size == 0:
        raise ParameterError(f"masks: expected a non-empty (N, H, W) stack, got {masks.shape}")
    if not np.any(masks > 0):
        raise ParameterError("masks: all patterns are black (transmittance 0 everywhere)")
    x, y = pixel_centres_mm(masks.shape[1:], pitch_mm)
    outside = (x[None, :] ** 2 + y[:, None] ** 2) > R_max * R_max * (1 + 1e-9)
    bad = np.flatnonzero(np.any((masks > 0) & outside[None], axis=(1, 2)))
    if bad.size:
        r_px = R_max / pitch_mm
        raise ParameterError(
            f"masks: pattern(s) {bad.tolist()} open pixels outside the lens (lens_radius = "
            f"{R_max:g} mm = {r_px:.1f} display px from the display centre); opening must be "
            f"inside the lens"
        )


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
