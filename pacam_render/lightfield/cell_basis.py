"""Every LCoS bitmap on a grid of cells at once: one image per (pattern window, cell).

The clear aperture's square (side 2 R_max, D = 2 R_max / pitch LCoS pixels) is cut into a
G x G grid of cells of D / G LCoS pixels each. A code A[k, c] in [0, 1], constant over each
cell c in pattern window k, is a bitmap design; its capture is linear in A, so with B[k, c]
the image of the store's samples of window k whose lens point falls in cell c (found with the
very LCoS pixel that :func:`~.codes.transmission` reads, then its cell), and F[k] = sum_c
B[k, c] the whole lens's (for the LCoS's contrast C):

    capture = sum_k sum_c A[k, c] B[k, c]                          (an ideal LCoS)
    capture = sum_k sum_c ((1 - 1/C) A[k, c] + 1/C) B[k, c]        (contrast C: the bitmap
            = (1 - 1/C) sum_k sum_c A[k, c] B[k, c] + sum_k F[k] / C  shows the leak as its
                                                                     masks' floor)

exactly the store's own synthesis (:func:`~.synthesis.synthesize`) of the bitmap design whose
masks are :meth:`CellBasis.masks` (same samples, weights and estimator): a design costs a
weighted sum of images, not a pass over the store. The focus, exposure and pattern windows are
the base design's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..model.masks import pixel_centres_mm
from .store import Store
from .synthesis import _resolve, _scene, check_passes, weighted_samples

CELL_CHOICES = (8, 16, 32, 64)
"""Cell grids the basis builds (G x G); each must divide the display's D pixels across the
clear aperture (the prototype's 1024)."""
DEFAULT_CELLS = 32
"""The default grid (``pacam optimize --space bitmap --cells``), by error per cost in
``benchmarks/bench_cell_grid.py`` (RESULTS.md): against the prototype's disc on the LCoS's own
pixels synthesised from the same samples, the rasterisation's rms (noise taken out) is 1.05,
0.77, 0.38, 0.27 of the reference sensor noise (grasshopper-icx285-mono at 7000 photons/px/ms)
for G = 8, 16, 32, 64 (train 64x48, grey, spp
1024); 16 -> 32 halves it for 3.8x the memory, 32 -> 64 takes off 31 % more for 3.9x the memory
and 8x a composition's time (a 64 x 64 RGB basis of that small window is over
:data:`MAX_BASIS_BYTES`)."""
MAX_BASIS_BYTES = 3 * 2**30
"""The most memory a basis may take while it is built (float64 sums + float32 result)."""


@dataclass(frozen=True)
class CellBasis:
    """B[k, c] and F[k] of one store (module docstring), the mean over its passes.

    ``images`` is (n, M, H, W, C), capture units, over the M cells that the lens reaches
    (``cells_ij`` (M, 2): each one's row, column in the G x G grid, the row growing downwards
    and the column to the image's right, as a mask's); ``full`` is (n, H, W, C);
    ``display_px`` the D LCoS pixels across the clear aperture; ``pitch_mm`` the LCoS's;
    ``contrast`` the LCoS's, or None; ``spec`` the base capture.
    """

    images: np.ndarray
    full: np.ndarray
    cells: int
    cells_ij: np.ndarray
    display_px: int
    pitch_mm: float
    contrast: float | None
    spec: object
    samples: int

    @property
    def n_patterns(self) -> int:
        return self.images.shape[0]

    def check_code(self, code) -> np.ndarray:
        """``code`` as float64 (n, G, G), refused (naming it) outside [0, 1] or mis-shaped."""
        a = np.asarray(code, float)
        shape = (self.n_patterns, self.cells, self.cells)
        if a.shape != shape:
            raise ParameterError(f"code: shape {shape} (patterns, cells, cells), got {a.shape}")
        if not np.all(np.isfinite(a)) or a.min() < 0 or a.max() > 1:
            raise ParameterError(
                f"code: transmittances in [0, 1], got [{np.nanmin(a):.4g}, {np.nanmax(a):.4g}]"
            )
        return a

    def weights(self, code) -> np.ndarray:
        """The (n, M) weight of each basis image for ``code`` (the contrast's floor left out)."""
        a = self.check_code(code)
        return a[:, self.cells_ij[:, 0], self.cells_ij[:, 1]]

    def compose(self, code) -> np.ndarray:
        """The capture (H, W, C) of the bitmap design ``code`` (n, G, G) in [0, 1]."""
        w = self.weights(code)
        out = np.einsum("km,kmhwc->hwc", w, self.images, dtype=np.float64, optimize=True)
        if self.contrast is not None:
            out = out * (1.0 - 1.0 / self.contrast) + self.full.sum(axis=0) / self.contrast
        return out

    def masks(self, code) -> np.ndarray:
        """The (n, D, D) LCoS stack that shows ``code``: each cell D / G pixels square, the
        contrast's leak as the floor 1 / C (the plugin reads a bitmap's values as they are)."""
        a = self.check_code(code)
        if self.contrast is not None:
            a = a * (1.0 - 1.0 / self.contrast) + 1.0 / self.contrast
        m = self.display_px // self.cells
        out = np.repeat(np.repeat(a, m, axis=1), m, axis=2).astype(np.float32)
        return out * lens_pixels(self.display_px, self.pitch_mm)[None]


def display_px(R_max_mm: float, pitch_mm: float, cells: int) -> int:
    """D, the LCoS pixels across the clear aperture, checked to hold ``cells`` whole cells."""
    D = int(round(2.0 * R_max_mm / pitch_mm))
    if abs(D * pitch_mm - 2.0 * R_max_mm) > 1e-6 * R_max_mm:
        raise ParameterError(
            f"the clear aperture (2 R_max = {2 * R_max_mm:g} mm) is not a whole number of LCoS "
            f"pixels ({pitch_mm:g} mm): a cell grid needs one"
        )
    if int(cells) != cells or cells < 1 or cells > D or D % int(cells):
        ok = [g for g in CELL_CHOICES if g <= D and D % g == 0]
        raise ParameterError(
            f"`cells`: a grid of G x G cells with G dividing the {D} LCoS pixels across the clear "
            f"aperture (no finer than the LCoS), e.g. {ok}; got {cells!r}"
        )
    return D


def lens_pixels(D: int, pitch_mm: float) -> np.ndarray:
    """(D, D) bool: the LCoS pixels a design may open, those whose centre lies in the clear
    aperture (radius D pitch / 2; the design file's rule,
    :func:`~pacam_render.model.masks.open_reach2_mm2`)."""
    x, y = pixel_centres_mm((D, D), pitch_mm)
    R = D * pitch_mm / 2.0
    return x[None, :] ** 2 + y[:, None] ** 2 <= R * R * (1 + 1e-9)


def lens_cells(cells: int, R_mm: float) -> np.ndarray:
    """(M, 2) row, column of the cells of a G x G grid over [-R, R]^2 that the disc of radius
    R touches (the rest hold no lens point)."""
    e = np.linspace(-R_mm, R_mm, cells + 1)
    near = np.minimum(np.abs(e[:-1]), np.abs(e[1:])) * ((e[:-1] > 0) | (e[1:] < 0))
    touch = near[:, None] ** 2 + near[None, :] ** 2 < R_mm**2
    return np.argwhere(touch)


def estimate_bytes(n: int, m: int, h: int, w: int, c: int) -> int:
    """Peak memory of a basis of n windows x m cells on an h x w x c window: the float64
    sums of one channel at a time, the float32 result and the samples' bins."""
    return n * m * h * w * (8 + 4 * c + 4)


def cell_basis(store: Store, spec, cells: int = DEFAULT_CELLS, progress: bool = False,
               max_bytes: int = MAX_BASIS_BYTES, passes=None) -> CellBasis:  # fmt: skip
    """:class:`CellBasis` of ``store`` on a ``cells`` x ``cells`` grid, for ``spec``'s camera.

    Parameters
    ----------
    store : Store
    spec : CaptureSpec
        The base capture (a coded design whose focus, exposure and windows are kept), served
        by the store (:func:`~.synthesis.synthesize`'s checks).
    cells : int
        G, cells across the clear aperture; must divide its LCoS pixels (1024 for the
        prototype: 8 to 64 or finer).
    max_bytes : int
        Refuse (ParameterError, before any pass over the store) a basis whose memory
        (:func:`estimate_bytes`) exceeds this.
    passes : sequence of int, optional
        Only these store passes (:func:`~.synthesis.check_passes`; default all): the basis of
        a search that leaves the others to choose among its results.

    Returns
    -------
    CellBasis
    """
    _scene(store, spec, None)
    plan, params, design_plan = _resolve(store, spec)
    pitch, R = float(plan.cam.lcos_pitch_mm), float(plan.cam.R_max_mm)
    D = display_px(R, pitch, cells)
    G, per = int(cells), D // int(cells)
    ij = lens_cells(G, R)
    n, M = len(design_plan.is_open), len(ij)
    _, _, w, h = store.manifest.camera.window
    c, chosen = store.manifest.channels, check_passes(store, passes)
    need = estimate_bytes(n, M, h, w, c)
    if need > max_bytes:
        raise ParameterError(
            f"cells: a {G} x {G} basis of {n} windows on {w}x{h}x{c} px takes "
            f"{need / 2**30:.2f} GiB, over max_bytes {max_bytes / 2**30:.2f} GiB: take fewer "
            "cells or a smaller window"
        )
    slot = np.full(G * G, -1, np.int64)
    slot[ij[:, 0] * G + ij[:, 1]] = np.arange(M)  # -1: a cell no lens point reaches
    parts = list(_binned(store, plan, params, design_plan, (D, per, G, M), slot, progress,
                         chosen))  # fmt: skip
    bins = np.concatenate([b for b, _ in parts])
    L = np.concatenate([v for _, v in parts], axis=1)
    del parts
    size = n * M * h * w
    grid = np.empty((size, c), np.float32)  # contiguous (n, M, h, w, c): a matrix's view
    for ch in range(c):  # one float64 accumulator at a time
        grid[:, ch] = np.bincount(bins, L[ch], minlength=size + 1)[:size] / len(chosen)
    grid = grid.reshape(n, M, h, w, c)
    return CellBasis(grid, grid.sum(axis=1, dtype=np.float64).astype(np.float32), G, ij, D,
                     pitch, params.get("lcos_contrast"), plan.spec, len(bins))  # fmt: skip


def _binned(store, plan, params, design_plan, grid, slot, progress, passes):
    """Per shard: each sample's bin in B (window, cell, pixel; n M h w for none: outside the
    window, the exposure, a closed pattern or the display) and its weighted radiance
    (channels, samples), the cell from the LCoS pixel that :func:`~.codes.transmission`
    reads for a D x D stack, kept where :func:`lens_pixels` lets a mask open it."""
    D, per, G, M = grid
    _, _, w, h = store.manifest.camera.window
    hw = h * w
    pitch = plan.cam.lcos_pitch_mm
    allowed = lens_pixels(D, pitch)
    for _, rec, t, pix, weight in weighted_samples(store, plan, params, design_plan, progress,
                                                   passes):  # fmt: skip
        t = np.broadcast_to(np.asarray(t, float), pix.shape)
        inside = (t >= design_plan.t_open) & (t < design_plan.t_close)
        k = design_plan.pattern_at(np.clip(t, design_plan.t_open, design_plan.t_close))
        col = np.floor(D / 2.0 - rec["u"] / pitch).astype(np.int64)
        row = np.floor(D / 2.0 - rec["v"] / pitch).astype(np.int64)
        on = (col >= 0) & (col < D) & (row >= 0) & (row < D)
        on[on] = allowed[row[on], col[on]]  # a pixel the masks may open (lens_pixels)
        cell = np.where(on, slot[np.where(on, (row // per) * G + col // per, 0)], -1)
        keep = inside & design_plan.is_open[k] & (pix < hw) & (cell >= 0)
        rows = np.nonzero(keep)[0]
        bins = (k[rows] * M + cell[rows]) * hw + pix[rows]
        yield _blend(bins, rec["L"][:, rows] * weight[rows], k[rows], t[rows], design_plan,
                     params.get("lcos_switching"), M * hw)  # fmt: skip


def _blend(bins, values, k, t, design_plan, switch_ms, window_size):
    """With a switching LCoS (``switch_ms`` > 0), a sample tau into window k > 0's first t_s
    counts tau / t_s in window k and 1 - tau / t_s in window k - 1 (same cell and pixel, one
    window earlier: ``window_size`` bins), as :func:`~.codes.transmission` blends the
    patterns; else the bins and values as they are."""
    if not switch_ms:
        return bins, values
    tc = np.clip(t, design_plan.t_open, design_plan.t_close)
    f = np.clip((tc - design_plan.pattern_edges[k]) / switch_ms, 0.0, 1.0)
    old = (k > 0) & (f < 1.0)
    now = np.where(old, f, 1.0).astype(values.dtype)
    was = (1.0 - f[old]).astype(values.dtype)
    return (np.concatenate([bins, bins[old] - window_size]),
            np.concatenate([values * now, values[:, old] * was], axis=1))  # fmt: skip
