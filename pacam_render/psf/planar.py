"""The PSF of a point whose image moves in two dimensions: x along a mode's trajectory (the
aperture's held openings and the object's horizontal speed), y at a vertical speed.

The coded camera's parabola is horizontal, so an object moving with a vertical component has a
path that is no longer on one row, and the exact one-dimensional integration of
:func:`~pacam_render.psf.analytic.kernel_from_trajectory` does not apply. Here the path is
sampled at the midpoints of steps of at most ``step_px`` along it, and each sample deposits an
exactly pixel-integrated pillbox of the defocus radius (:mod:`.pillbox`): midpoint quadrature,
second order in the step (an in-focus point, r = 0, is binned, first order, on a 25 times finer
step). With no vertical speed it agrees with the exact kernel to the
quadrature's error (tested); a vertical path is the exact kernel's transpose.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from .grid import R_DELTA_PX, kernel_shape, normalise
from .pillbox import quadrant_area
from .trajectory import Segment, extent, total_weight

STEP_PX = 0.05
"""Default largest path length between quadrature samples, px."""
POINT_REFINE = 25
"""With r = 0 the step is this much finer: binning points into pixels is first order (L1 5.5e-3
against the exact in-focus kernel at 0.05 px, 2.7e-4 at 0.002 px)."""
_CHUNK = 2_000_000
"""Values evaluated at once when depositing discs (bounds the memory to ~100 MB)."""


def planar_kernel(
    segments: list[Segment],
    r_px: float,
    v_px_per_ms: float,
    size=None,
    step_px: float = STEP_PX,
) -> np.ndarray:
    """Pixel-integrated PSF of a point at (x(t), v t), x(t) from ``segments``, blurred by a
    pillbox of radius ``r_px`` (Eq. 13).

    Parameters
    ----------
    segments : list of Segment
        The horizontal trajectory and shutter weights over the exposure
        (:func:`~pacam_render.psf.analytic.design_trajectory`).
    r_px : float
        Defocus radius r = |beta| R (Eq. 12), px; below ``R_DELTA_PX`` a delta.
    v_px_per_ms : float
        Vertical image speed, px/ms (rows, downwards); t = 0 is at the kernel's centre row.
    size : int or (int, int), optional
        Odd kernel shape; default: just large enough.
    step_px : float, optional
        Largest path length between samples, px.

    Returns
    -------
    numpy.ndarray
        The kernel, odd-sized, summing to 1, centred at the origin.
    """
    r = float(r_px)
    if not math.isfinite(r) or r < 0:
        raise ParameterError(f"r_px must be a finite radius >= 0 px, got {r_px!r}")
    r = 0.0 if r < R_DELTA_PX else r
    v = check_finite("v_px_per_ms", v_px_per_ms)
    step = check_positive("step_px", step_px, "px")
    # a point (r = 0) is binned, which is first order in the step: sample it finer (cheap)
    x, y, mass = _samples(segments, v, step if r > 0.0 else step / POINT_REFINE)
    if size is None:
        lo, hi = extent(segments)
        w = kernel_shape(None, lo, hi, r)[1]
        h = 2 * math.ceil(float(np.abs(y).max()) + r + 0.5) + 1
        size = (h, w)
    kernel = np.zeros(kernel_shape(size, 0.0, 0.0, r))
    if r == 0.0:
        _deposit_points(kernel, x, y, mass)
    else:
        _deposit_discs_2d(kernel, x, y, r, mass / (math.pi * r * r))
    return normalise(kernel, total_weight(segments))


def _samples(segments: list[Segment], v: float, step: float):
    """Midpoint samples of the path: x, y (px) and the time each stands for (x weight), ms."""
    xs, ys, ms = [], [], []
    for seg in segments:
        dt = seg.t1 - seg.t0
        if dt <= 0.0 or seg.w == 0.0:
            continue
        t_max = max(abs(seg.t0), abs(seg.t1))
        speed = math.hypot(abs(seg.v) + abs(seg.a) * t_max, v)
        n = max(1, math.ceil(speed * dt / step))
        t = seg.t0 + (np.arange(n) + 0.5) * (dt / n)
        xs.append(seg.x(t))
        ys.append(seg.y + v * t)
        ms.append(np.full(n, seg.w * dt / n))
    if not xs:
        raise ParameterError("the trajectory has no open time: no PSF")
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(ms)


def _deposit_points(kernel, x, y, mass) -> None:
    """r = 0: each sample's time goes to the pixel that holds it."""
    h, w = kernel.shape
    j = np.floor(x + w // 2 + 0.5).astype(np.int64)
    i = np.floor(y + h // 2 + 0.5).astype(np.int64)
    ok = (i >= 0) & (i < h) & (j >= 0) & (j < w)
    kernel += np.bincount(i[ok] * w + j[ok], weights=mass[ok], minlength=h * w).reshape(h, w)


def _deposit_discs_2d(kernel, x, y, r: float, density) -> None:
    """Add density x (area of a disc of radius r at (x, y) in each pixel) to the kernel.

    The area in a pixel is the four-corner difference of the quadrant areas
    A(x, y) = |disc and {X <= x, Y <= y}|, evaluated on each disc's own small grid."""
    h, w = kernel.shape
    n = math.ceil(2 * r) + 2  # pixels a disc can touch along each axis
    grid = np.arange(n + 1)
    chunk = max(1, _CHUNK // ((n + 1) ** 2))
    for k in range(0, x.size, chunk):
        cx, cy, m = x[k : k + chunk], y[k : k + chunk], density[k : k + chunk]
        j0 = np.floor(cx - r + w // 2 + 0.5).astype(np.int64)  # first column a disc can touch
        i0 = np.floor(cy - r + h // 2 + 0.5).astype(np.int64)
        dx = (j0[:, None] + grid - w // 2 - 0.5) - cx[:, None]  # column edges from the centre
        dy = (i0[:, None] + grid - h // 2 - 0.5) - cy[:, None]
        a = quadrant_area(dx[:, None, :], dy[:, :, None], r)
        cov = (a[:, 1:, 1:] - a[:, :-1, 1:] - a[:, 1:, :-1] + a[:, :-1, :-1]) * m[:, None, None]
        ii = i0[:, None, None] + grid[None, :-1, None]
        jj = j0[:, None, None] + grid[None, None, :-1]
        ii, jj = np.broadcast_to(ii, cov.shape), np.broadcast_to(jj, cov.shape)
        ok = (ii >= 0) & (ii < h) & (jj >= 0) & (jj < w) & (cov > 0.0)
        kernel += np.bincount(ii[ok] * w + jj[ok], weights=cov[ok], minlength=h * w).reshape(h, w)
