"""Analytic, pixel-integrated PSF of an aperture that shows a stack of LCoS bitmaps (issue 35).

Geometry (the plugin's, :mod:`pacam_render.model.masks`): pattern k of an ``(N, H, W)`` stack is
shown during the k-th of N equal windows of [-T, T] (:func:`~pacam_render.model.schedule.
pattern_edges_ms`). LCoS pixel (i, j) sits at X = (j + 1/2 - W/2) p, Y = (i + 1/2 - H/2) p mm
in the design frame (x to the image's right, y downwards; p the pitch), so through it a still
point images at (u, v) = beta (X, Y) px from its pinhole image (Eq. 8), and the pixel's square
opening images as a square of side b = |beta| p px. Its irradiance weight in window k is
tau_k(i, j) p^2 (t1 - t0). A point moving at s px/ms along +u sweeps each square over
[s t0, s t1] during the window: along u the light of one LCoS pixel is the box of width b
convolved with the box of the sweep (a trapezoid), along v the box of width b.

Method: both profiles are separable and their cumulative distributions are closed-form, so the
mass of LCoS pixel (i, j) in kernel pixel (a, c) is exactly Pv[a, i] Pu[c, j], the differences
of those distributions across the kernel's pixel edges, and a pattern's kernel is the matrix
product Pv tau_k Pu^T over the bounding box of its open pixels. Nothing is sampled: with
v_px_per_ms = 0 the kernel is exact to rounding, and the footprint costs nothing.

Error against run time (one shared core): a random 4 x 12 x 16 grey stack at beta = -60 px/mm
(squares of 0.82 px), s = 0.3 px/ms, T = 22.5 ms, 41 x 41 kernel. This module: 1.2 ms. Brute
force, stratified as ``brute`` in ``tests/psf/test_bitmap.py`` (n x n jittered points per LCoS
pixel, 4n jittered times per window, histogrammed): L1 to this kernel 4.1e-3
(n = 8, 0.1 s), 1.1e-3 (16, 2 s), 2.8e-4 (32, 8 s), 7.3e-5 (64, 70 s): the reference's own
error, falling 4x per doubling. The same on a regular grid stalls at 6e-3 (64, 75 s).
Speed on the prototype's 1024 x 1280 display, 16 patterns: discs of R = 1.98 mm (beta =
-1.01 px/mm): 28-49 ms at s = 0 or 0.5 (half of it the two passes that check the stack);
16 random full-display grey patterns: 0.16-0.37 s (ranges: a loaded 2-core machine).

With a vertical speed v_px_per_ms as well, the slower axis is midpoint quadrature on time steps
of at most ``du_px`` of travel, held at the step's mid-time; the faster axis stays exact.
Second order: L1 1.0e-4 at the default 0.05 px and 3e-6 at 0.01 px (against 0.005 px) for
those 16 discs at s = 0.4, v = 0.3 px/ms; 0.13-0.29 s at the default (s = 0.5, v = 0.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model import schedule as sch
from ..model.masks import load_masks
from .grid import MAX_LOST_FRACTION, auto_size, kernel_shape, normalise
from .planar import STEP_PX

_TINY = 4e-8
"""Below this ratio of the sweep to the square (or back) the trapezoid is its wider box: the
error is ~ ratio / 8, and the closed form would lose ~ 2e-16 / ratio to cancellation."""

ORIGINS = ("t0", "pinhole")

MAX_STEPS = 20_000
"""Most quadrature steps (planar motion) in one kernel: ~20 s for 16 prototype discs."""


@dataclass(frozen=True)
class _Setup:
    """A checked stack and camera: everything the kernel, extent and lost mass read."""

    masks: np.ndarray  # (N, H, W), float
    boxes: list  # per pattern: (r0, r1, c0, c1) of the open pixels, or None if black
    mass: np.ndarray  # (N,) summed transmittance
    u: np.ndarray  # (W,) u of each column's centre in the kernel's frame, px
    v: np.ndarray  # (H,) v of each row's centre, px
    b: float  # side of an LCoS pixel's image, px
    edges_ms: np.ndarray  # (N + 1,) window edges
    s: float
    vy: float
    du: float


def _check_stack(masks) -> tuple[np.ndarray, np.ndarray]:
    """A float ``(N, H, W)`` stack in [0, 1] with some light, and each row's largest value
    ``(N, H)``; ParameterError naming ``masks``. Two passes over the stack, the least here."""
    arr = masks if isinstance(masks, np.ndarray) else np.asarray(masks)
    if arr.dtype.kind not in "fc" or arr.ndim not in (2, 3):  # integers, bools, odd shapes
        arr = load_masks(arr, "masks")
    if arr.dtype.kind == "c":
        raise ParameterError("masks: transmittance must be real, got complex values")
    arr = arr[None] if arr.ndim == 2 else arr
    if arr.size == 0:
        raise ParameterError(f"masks: empty stack (shape {arr.shape})")
    row_max = arr.max(axis=2)  # NaN propagates through max and min
    lo, hi = float(arr.min()), float(row_max.max())
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParameterError("masks: transmittance must be finite (found NaN or inf)")
    if lo < 0.0 or hi > 1.0:
        raise ParameterError(f"masks: transmittance must be in [0, 1], got [{lo:g}, {hi:g}]")
    if hi == 0.0:
        raise ParameterError("masks: all patterns are black (transmittance 0 everywhere)")
    return arr, row_max


def _open_boxes(masks: np.ndarray, row_max: np.ndarray) -> tuple[list, np.ndarray]:
    """Bounding box of each pattern's open pixels (None if black), and its total transmittance."""
    boxes, mass = [], np.zeros(masks.shape[0])
    for k, m in enumerate(masks):
        rows = np.flatnonzero(row_max[k] > 0.0)
        if rows.size == 0:
            boxes.append(None)
            continue
        band = m[rows[0] : rows[-1] + 1]
        cols = np.flatnonzero(band.max(axis=0) > 0.0)
        boxes.append((int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1))
        mass[k] = float(band[:, cols[0] : cols[-1] + 1].sum(dtype=np.float64))
    return boxes, mass


def _lattice(n: int, pitch: float, beta: float) -> np.ndarray:
    """beta times the design-frame coordinate of n pixel centres along one axis, px (Eq. 8)."""
    return beta * ((np.arange(n) + 0.5 - 0.5 * n) * pitch)


def _centroid(mask: np.ndarray, box, mass: float, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transmittance-weighted (u, v) of one pattern (pixel centres at u[j], v[i]); NaN if black."""
    if box is None:
        return np.full(2, np.nan)
    r0, r1, c0, c1 = box
    m = mask[r0:r1, c0:c1]
    cu = float(m.sum(axis=0, dtype=np.float64) @ u[c0:c1]) / mass
    cv = float(m.sum(axis=1, dtype=np.float64) @ v[r0:r1]) / mass
    return np.array([cu, cv])


def _setup(masks, pitch_mm, beta_px_per_mm, T_ms, s, x0_px, v_px_per_ms, du_px, origin):
    """Check every input once and lay the stack out in the kernel's frame."""
    if origin not in ORIGINS:
        raise ParameterError(f"origin must be one of {', '.join(ORIGINS)}, got {origin!r}")
    arr, row_max = _check_stack(masks)
    pitch = check_positive("pitch_mm", pitch_mm, "mm")
    beta = check_finite("beta_px_per_mm", beta_px_per_mm)
    edges = sch.pattern_edges_ms(T_ms, arr.shape[0])
    s, vy = check_finite("s (px/ms)", s), check_finite("v_px_per_ms", v_px_per_ms)
    du = STEP_PX if du_px is None else check_positive("du_px", du_px, "px")
    steps = arr.shape[0] * math.ceil(min(abs(s), abs(vy)) * (edges[1] - edges[0]) / du)
    if steps > MAX_STEPS:
        raise ParameterError(
            f"s = {s:g} and v_px_per_ms = {vy:g} px/ms need {steps} quadrature steps of "
            f"du_px = {du:g} px, more than {MAX_STEPS}: give a larger du_px"
        )
    boxes, mass = _open_boxes(arr, row_max)
    u, v = _lattice(arr.shape[2], pitch, beta), _lattice(arr.shape[1], pitch, beta)
    shift = check_finite("x0_px", x0_px)
    if origin == "t0":  # as held_offsets_px: u from the pattern shown at t = 0, v unchanged
        k0 = int(sch.pattern_index(0.0, T_ms, arr.shape[0]))
        if boxes[k0] is None:
            raise ParameterError(
                f"origin 't0': pattern {k0}, shown at t = 0, is black, so the point has no "
                "image at t = 0; use origin 'pinhole'"
            )
        shift -= _centroid(arr[k0], boxes[k0], mass[k0], u, v)[0]
    return _Setup(arr, boxes, mass, u + shift, v, abs(beta) * pitch, edges, s, vy, du)


def _sweeps(st: _Setup):
    """Yield (k, time weight ms, (u0, u1), (v0, v1)): the sweep of each open pattern's window.

    With both speeds non-zero the window is cut into steps of at most ``du`` of travel along
    the slower axis, which is held at the step's mid-time (midpoint rule); the faster is swept.
    """
    slow = min(abs(st.s), abs(st.vy))
    u_fast = abs(st.s) >= abs(st.vy)
    for k, box in enumerate(st.boxes):
        if box is None:
            continue
        t0, t1 = st.edges_ms[k], st.edges_ms[k + 1]
        n = max(1, math.ceil(slow * (t1 - t0) / st.du))
        ts = np.linspace(t0, t1, n + 1)
        for ta, tb in zip(ts[:-1], ts[1:]):
            tm = 0.5 * (ta + tb)
            us = sorted((st.s * ta, st.s * tb)) if u_fast else (st.s * tm,) * 2
            vs = (st.vy * tm,) * 2 if u_fast else sorted((st.vy * ta, st.vy * tb))
            yield k, tb - ta, us, vs


def _cdf(z: np.ndarray, b: float, L: float) -> np.ndarray:
    """Fraction of a box of width b swept over length L that lies below z (z from its start)."""
    if b == 0.0 and L == 0.0:  # a point: the kernel's pixels are half-open [lo, hi)
        return (z > 0.0).astype(float)
    if L <= _TINY * b:  # held: the box at the sweep's middle
        return np.clip((z - 0.5 * L) / b, 0.0, 1.0)
    if b <= _TINY * L:  # a point swept over L
        return np.clip((z - 0.5 * b) / L, 0.0, 1.0)
    zc = np.clip(z, 0.0, b + L)  # only [0, b + L] is not 0 or 1: no cancellation beyond it

    def ramp(y):  # integral of the box's distribution, from its start
        return np.where(y <= 0.0, 0.0, np.where(y < b, 0.5 * y * y / b, y - 0.5 * b))

    return (ramp(zc) - ramp(zc - L)) / L


def _profile(centres: np.ndarray, b: float, sweep, edges: np.ndarray):
    """Mass of each LCoS row or column (centre c) in each kernel pixel along one axis.

    Returns the first kernel pixel touched and P (pixels, centres); (0, None) if none is.
    """
    m0, m1 = sweep
    lo = float(centres.min()) + m0 - 0.5 * b  # the trapezoids' union
    hi = float(centres.max()) + m1 + 0.5 * b
    n = edges.size - 1
    ia = max(int(np.searchsorted(edges, lo)) - 1, 0)
    ib = min(int(np.searchsorted(edges, hi)) + 1, n)
    if ia >= ib:
        return 0, None
    z = edges[ia : ib + 1, None] - (centres[None, :] + m0 - 0.5 * b)
    return ia, np.diff(_cdf(z, b, m1 - m0), axis=0)


def _inside(centres: np.ndarray, b: float, sweep, edges: np.ndarray) -> np.ndarray:
    """Fraction of each row's or column's light that falls between the kernel's outer edges."""
    m0, m1 = sweep
    z = edges[[0, -1], None] - (centres[None, :] + m0 - 0.5 * b)
    f = _cdf(z, b, m1 - m0)
    return f[1] - f[0]


def _grid(st: _Setup, size):
    """The kernel's shape and pixel edges (u across, v down), centred on the origin."""
    if size is None:
        u_lo, u_hi, v_lo, v_hi = _extent(st)
        n = auto_size(min(u_lo, v_lo), max(u_hi, v_hi), 0.0)
        size = (n, n)
    h, w = kernel_shape(size, 0.0, 0.0, 0.0)
    return (h, w), np.arange(w + 1) - w // 2 - 0.5, np.arange(h + 1) - h // 2 - 0.5


def _extent(st: _Setup) -> tuple[float, float, float, float]:
    """Smallest box (u_lo, u_hi, v_lo, v_hi) px that holds all the light, from the origin."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for k, _w, us, vs in _sweeps(st):
        r0, r1, c0, c1 = st.boxes[k]
        for ax, (c, sweep) in enumerate(((st.u[[c0, c1 - 1]], us), (st.v[[r0, r1 - 1]], vs))):
            lo[ax] = min(lo[ax], float(c.min()) + sweep[0] - 0.5 * st.b)
            hi[ax] = max(hi[ax], float(c.max()) + sweep[1] + 0.5 * st.b)
    return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def _lost(st: _Setup, xe: np.ndarray, ye: np.ndarray) -> float:
    """Exact fraction of the light that falls outside the kernel: O(open pixels), no kernel."""
    inside = total = 0.0
    for k, w, us, vs in _sweeps(st):
        r0, r1, c0, c1 = st.boxes[k]
        fu = _inside(st.u[c0:c1], st.b, us, xe)
        fv = _inside(st.v[r0:r1], st.b, vs, ye)
        inside += w * float(fv @ (st.masks[k, r0:r1, c0:c1] @ fu))
        total += w * st.mass[k]
    return max(0.0, 1.0 - inside / total)


def bitmap_offsets_px(masks, pitch_mm: float, beta_px_per_mm: float) -> np.ndarray:
    """Where each pattern images a still point: its light's centroid, px from the pinhole image.

    Parameters
    ----------
    masks : array_like
        ``(N, H, W)`` (or ``(H, W)``) transmittance stack in [0, 1], in the orientation of
        :mod:`pacam_render.model.masks`.
    pitch_mm : float
        The display's pixel pitch, mm.
    beta_px_per_mm : float
        Signed image shift per mm of aperture offset (Eq. 8), px/mm; < 0 beyond focus.

    Returns
    -------
    numpy.ndarray
        ``(N, 2)`` offsets (u, v), px (u to the right, v down): beta times the
        transmittance-weighted centroid (X, Y) of the pattern in the design frame; a NaN row
        for an all-black pattern. For a disc this is ``pattern_offsets_px`` of the design.
    """
    arr, row_max = _check_stack(masks)
    pitch = check_positive("pitch_mm", pitch_mm, "mm")
    beta = check_finite("beta_px_per_mm", beta_px_per_mm)
    boxes, mass = _open_boxes(arr, row_max)
    u, v = _lattice(arr.shape[2], pitch, beta), _lattice(arr.shape[1], pitch, beta)
    return np.array([_centroid(m, bx, ms, u, v) for m, bx, ms in zip(arr, boxes, mass)])


def bitmap_extent_px(
    masks,
    pitch_mm: float,
    beta_px_per_mm: float,
    T_ms: float,
    s: float = 0.0,
    x0_px: float = 0.0,
    v_px_per_ms: float = 0.0,
    origin: str = "t0",
) -> tuple[float, float, float, float]:
    """The smallest box, px from the kernel's centre, that holds all of the PSF's light.

    Parameters
    ----------
    masks, pitch_mm, beta_px_per_mm, T_ms, s, x0_px, v_px_per_ms, origin
        As for :func:`bitmap_kernel`.

    Returns
    -------
    (u_lo, u_hi, v_lo, v_hi) : tuple of float
        Bounds along u (right) and v (down), px; the automatic kernel is the smallest odd
        square that contains the box (at most ``grid.MAX_AUTO_SIZE``).
    """
    st = _setup(masks, pitch_mm, beta_px_per_mm, T_ms, s, x0_px, v_px_per_ms, None, origin)
    return _extent(st)


def bitmap_lost_fraction(
    masks,
    pitch_mm: float,
    beta_px_per_mm: float,
    T_ms: float,
    s: float = 0.0,
    size=None,
    x0_px: float = 0.0,
    v_px_per_ms: float = 0.0,
    du_px: float | None = None,
    origin: str = "t0",
) -> tuple[float, tuple[int, int]]:
    """The exact fraction of the PSF's light outside its kernel, without building the kernel.

    Costs one pass over the open pixels (a matrix-vector product per pattern), so a caller can
    refuse a kernel (a huge defocus) before paying for it.

    Parameters
    ----------
    masks, pitch_mm, beta_px_per_mm, T_ms, s, size, x0_px, v_px_per_ms, du_px, origin
        As for :func:`bitmap_kernel`.

    Returns
    -------
    lost : float
        The fraction, in [0, 1].
    shape : (int, int)
        The kernel's (h, w): ``size``, or the automatic size.
    """
    st = _setup(masks, pitch_mm, beta_px_per_mm, T_ms, s, x0_px, v_px_per_ms, du_px, origin)
    shape, xe, ye = _grid(st, size)
    return _lost(st, xe, ye), shape


def bitmap_kernel(
    masks,
    pitch_mm: float,
    beta_px_per_mm: float,
    T_ms: float,
    s: float = 0.0,
    size=None,
    x0_px: float = 0.0,
    v_px_per_ms: float = 0.0,
    du_px: float | None = None,
    origin: str = "t0",
    max_lost: float = MAX_LOST_FRACTION,
) -> np.ndarray:
    """The pixel-integrated PSF of a still or moving point seen through a bitmap stack.

    Exact closed-form integration of each LCoS pixel's image (a square of side |beta| p,
    Eq. 8, swept by the motion) over the kernel's pixels; see the module's notes for the
    method, its error and its speed. A disc stack gives the designed schedule's kernel
    (Eqs. 12-13: its defocus radius is |beta| R) up to the disc's rasterisation.

    Parameters
    ----------
    masks : array_like
        ``(N, H, W)`` (or ``(H, W)``) transmittance in [0, 1] (8/16-bit code values and bools
        are read as in :func:`~pacam_render.model.masks.load_masks`); pattern k is shown in the
        k-th of N equal windows of [-T, T]. All-black patterns shut the aperture in their
        window; the kernel is normalised over the light that passes.
    pitch_mm : float
        The display's pixel pitch, mm.
    beta_px_per_mm : float
        Signed image shift per mm of aperture offset (Eq. 8), px/mm: < 0 when the object is
        beyond the focal plane; 0 in focus (every opening images at one point).
    T_ms : float
        Half the exposure, ms.
    s : float
        Image speed along +u (columns, to the right), px/ms; u = s t, t = 0 mid-exposure.
    size : int or (int, int), optional
        Odd kernel size; default: the smallest odd square holding all of the light
        (:func:`bitmap_extent_px`), at most ``grid.MAX_AUTO_SIZE``.
    x0_px : float
        Where the origin's image lies in the kernel, px along u: the whole PSF moves by
        +x0_px (as ``designed_segments``'s x0_px).
    v_px_per_ms : float
        Image speed along +v (rows, downwards), px/ms; v = v_px_per_ms t.
    du_px : float, optional
        With both speeds non-zero: the largest travel (px) along the slower axis per
        quadrature step (default ``planar.STEP_PX``); unused otherwise.
    origin : {"t0", "pinhole"}
        What the centre pixel stands for. ``"pinhole"``: the pinhole image (a pixel at display
        (X, Y) images at beta (X, Y)). ``"t0"``: along u, the centroid of the pattern shown at
        t = 0 (pattern N // 2, :func:`bitmap_offsets_px`), along v the pinhole's row, as
        ``held_offsets_px`` for a designed schedule; refused if that pattern is black.
    max_lost : float
        Refuse (ParameterError) a kernel that would lose more than this fraction of the light
        (exact, computed before the kernel); a smaller loss warns (PSFTruncationWarning).

    Returns
    -------
    numpy.ndarray
        The kernel, float64, odd-sized, centred on ``origin``, each value the PSF integrated
        over the pixel, summing to 1.

    Examples
    --------
    One open LCoS pixel, 2.5 pitches right of the display's centre, seen from beyond the focal
    plane (beta < 0): a point 2.55 px left of the pinhole image, swept right by s 2T = 9 px.

    >>> m = np.zeros((1, 4, 6)); m[0, 2, 5] = 1.0
    >>> k = bitmap_kernel(m, pitch_mm=0.1, beta_px_per_mm=-10.2, T_ms=22.5, s=0.2,
    ...                   origin="pinhole")
    >>> k.shape, round(float(k.sum()), 12), bitmap_offsets_px(m, 0.1, -10.2).round(2).tolist()
    ((19, 19), 1.0, [[-2.55, -0.51]])
    >>> round(float(k.sum(axis=0) @ (np.arange(19) - 9)), 2)  # the centroid, px
    -2.55
    """
    st = _setup(masks, pitch_mm, beta_px_per_mm, T_ms, s, x0_px, v_px_per_ms, du_px, origin)
    (h, w), xe, ye = _grid(st, size)
    lost = _lost(st, xe, ye)
    if lost > max_lost:  # checked first: a huge defocus would otherwise cost the full product
        raise ParameterError(
            f"{lost:.3%} of the PSF falls outside the {h}x{w} kernel (an LCoS pixel images "
            f"to {st.b:.3g} px), more than max_lost = {max_lost:g}; give a larger size (the "
            "automatic size stops at 2049 px) or a smaller |beta_px_per_mm| or |s|"
        )
    kernel = np.zeros((h, w))
    for k, wt, us, vs in _sweeps(st):
        _deposit(kernel, st, k, wt, us, vs, xe, ye)
    return normalise(kernel, float(st.mass @ np.diff(st.edges_ms)))


def _deposit(kernel, st: _Setup, k: int, wt: float, us, vs, xe, ye) -> None:
    """Add one sweep of pattern k: Pv tau Pu^T, multiplied in the cheaper order."""
    r0, r1, c0, c1 = st.boxes[k]
    ja, pu = _profile(st.u[c0:c1], st.b, us, xe)
    ia, pv = _profile(st.v[r0:r1], st.b, vs, ye)
    if pu is None or pv is None:
        return
    tau = st.masks[k, r0:r1, c0:c1].astype(np.float64)
    (ni, nr), (nj, nc) = pv.shape, pu.shape
    if ni * nr * nc + ni * nc * nj <= nr * nc * nj + ni * nr * nj:
        block = (pv @ tau) @ pu.T
    else:
        block = pv @ (tau @ pu.T)
    kernel[ia : ia + ni, ja : ja + nj] += wt * block
