"""The convolution model of a whole scene: Eq. 14 applied surface by surface, from a capture's
ground-truth layers (:mod:`pacam_render.exposure.truth`).

A ray tracer images every surface point through the moving aperture and the moving geometry.
The model the paper deblurs with says instead that each surface is its sharp image convolved
with the PSF of its own depth and velocity (r = |beta| R and a_i = beta a_a at its depth,
Eqs. 12 and 18; the object's speed s in Eq. 2; the discrete 16-pattern schedule). Pixels are
grouped into *cells* of one object whose PSFs differ by less than ``quantum_px``: the depth's
beta quantised so that the aperture's image offsets (up to beta R_max) move by at most one
quantum, and the velocity so that the motion over T moves by at most one quantum.

Two ways of putting the cells together are built, and they differ only near edges:

``composite``
    Each pixel takes its own cell's PSF convolved with the *whole* sharp image (a spatially
    varying blur: what a deblurring that picks the kernel per region assumes).
``layered``
    Each cell's sharp pixels are convolved with its PSF and the results added (each surface
    blurred on its own, as in layered models; what is hidden at t = 0 is missing).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from ..errors import ParameterError, check_positive
from ..model.camera import MIN_FOCUS_MM, CameraDesign
from .analytic import design_psf

QUANTUM_PX = 0.25
"""Default cell quantum, px of the PSF's geometry (see the module docstring)."""
FAR_MM = 1e9
"""The depth given to pixels where no surface is seen (the background at infinity), mm."""
MODEL_MODES = ("coded", "coded_continuous", "normal", "short", "flutter")
"""Modes whose PSF at any depth follows from the capture camera (Levin's body motion does not
scale with depth like an aperture's parallax, so it is left out)."""


@dataclass
class Cell:
    """Pixels of one object that share one PSF: the medians of their depth and velocity."""

    object_id: int
    depth_mm: float
    u_px_per_ms: float
    v_px_per_ms: float
    kernel: np.ndarray
    rows: np.ndarray
    cols: np.ndarray

    @property
    def reach_px(self) -> float:
        """How far the kernel's mass reaches from its origin, px (Euclidean, to pixel centres)."""
        h, w = self.kernel.shape
        i, j = np.nonzero(self.kernel > 0.0)
        return float(np.hypot(i - h // 2, j - w // 2).max())

    @property
    def moving(self) -> bool:
        return self.u_px_per_ms != 0.0 or self.v_px_per_ms != 0.0


@dataclass
class SceneModel:
    """The model images (H, W, 3) and what they are made of."""

    composite: np.ndarray
    layered: np.ndarray
    cells: list[Cell]
    seconds: float

    @property
    def reach_px(self) -> float:
        """The farthest any cell's PSF reaches, px."""
        return max(c.reach_px for c in self.cells)


def beta_px_per_mm(depth_mm: np.ndarray, camera: CameraDesign) -> np.ndarray:
    """beta of Eq. 9 at each depth, px of image shift per mm of aperture offset (0: infinity)."""
    z = np.where(depth_mm > 0, depth_mm, np.inf)
    return (1.0 / camera.focus_distance_mm - 1.0 / z) * camera.focal_length_px


def cell_labels(layers: dict, camera: CameraDesign, quantum_px: float) -> tuple[np.ndarray, int]:
    """Each pixel's cell (0..n-1) by object, quantised beta and quantised velocity.

    Returns
    -------
    labels : ndarray
        (H, W) integer cell index.
    n : int
        The number of cells.
    """
    q = check_positive("quantum_px", quantum_px, "px")
    beta = beta_px_per_mm(layers["depth"], camera)
    vel = layers["velocity"]
    key = np.stack(
        [
            layers["object_id"].astype(np.int64),
            np.rint(beta * camera.R_max_mm / q).astype(np.int64),
            np.rint(vel[..., 0] * camera.T_ms / q).astype(np.int64),
            np.rint(vel[..., 1] * camera.T_ms / q).astype(np.int64),
        ],
        -1,
    ).reshape(-1, 4)
    _, labels = np.unique(key, axis=0, return_inverse=True)
    labels = labels.reshape(layers["depth"].shape)
    return labels, int(labels.max()) + 1


def build_cells(
    layers: dict, camera: CameraDesign, mode: str, quantum_px: float = QUANTUM_PX
) -> list[Cell]:
    """The cells of a truth window with their PSFs (registered to the pinhole image).

    Parameters
    ----------
    layers : dict
        ``depth`` (mm, 0: none), ``object_id`` and ``velocity`` (px/ms) of the window.
    camera : CameraDesign
        The capture camera (:func:`~pacam_render.model.modes.capture_camera`), at the
        capture's resolution.
    mode : str
        One of :data:`MODEL_MODES`.
    quantum_px : float, optional
        The cell quantum, px.
    """
    if mode not in MODEL_MODES:
        raise ParameterError(f"mode must be one of {', '.join(MODEL_MODES)}, got {mode!r}")
    labels, n = cell_labels(layers, camera, quantum_px)
    flat = labels.ravel()
    order = np.argsort(flat, kind="stable")
    bounds = np.searchsorted(flat[order], np.arange(n + 1))
    cells = []
    for k in tqdm(range(n), desc="PSFs", unit="cell", delay=2.0, disable=None, leave=False):
        idx = order[bounds[k] : bounds[k + 1]]
        rows, cols = np.unravel_index(idx, labels.shape)
        cells.append(_cell(layers, camera, mode, rows, cols, quantum_px))
    return cells


def _cell(layers, camera: CameraDesign, mode: str, rows, cols, quantum_px: float) -> Cell:
    depth = layers["depth"][rows, cols]
    z = float(np.median(np.where(depth > 0, depth, FAR_MM)))
    if z < MIN_FOCUS_MM:
        raise ParameterError(
            f"a surface at {z:.4g} mm is closer than the thin-lens model's {MIN_FOCUS_MM:g} mm"
        )
    u, v = (float(np.median(layers["velocity"][rows, cols, i])) for i in (0, 1))
    # a velocity within half a quantum of zero is zero: the exact one-dimensional kernel
    u, v = (0.0 if abs(x) * camera.T_ms < 0.5 * quantum_px else x for x in (u, v))
    kernel = design_psf(camera.with_(object_depth_mm=z), mode, u, origin="pinhole", v_px_per_ms=v)
    oid = int(layers["object_id"][rows[0], cols[0]])
    return Cell(oid, z, u, v, kernel, rows, cols)


def convolution_model(
    sharp: np.ndarray,
    layers: dict,
    camera: CameraDesign,
    mode: str = "coded",
    quantum_px: float = QUANTUM_PX,
) -> SceneModel:
    """The capture the convolution model predicts from the sharp image and its layers.

    Parameters
    ----------
    sharp : ndarray
        (H, W, 3) the t = 0 pinhole image, on the capture's scale.
    layers : dict
        Its ``depth``, ``object_id`` and ``velocity`` layers (see :func:`build_cells`).
    camera : CameraDesign
        The capture camera at the capture's resolution.
    mode : str, optional
        The capture mode, one of :data:`MODEL_MODES`.
    quantum_px : float, optional
        The cell quantum, px: smaller is closer to per-pixel PSFs and slower.

    Returns
    -------
    SceneModel
        ``composite`` and ``layered`` (see the module docstring); pixels whose PSF reads
        beyond the window are wrong by what the window does not hold.
    """
    t0 = time.perf_counter()
    cells = build_cells(layers, camera, mode, quantum_px)
    py = max(c.kernel.shape[0] // 2 for c in cells)
    px = max(c.kernel.shape[1] // 2 for c in cells)
    pad = ((py, py), (px, px), (0, 0))
    src = np.pad(np.asarray(sharp, np.float64), pad)
    composite = np.zeros_like(sharp, dtype=np.float64)
    layered = np.zeros_like(src)
    for c in cells:
        _add_cell(c, src, composite, layered, (py, px))
    h, w = sharp.shape[:2]
    seconds = time.perf_counter() - t0
    return SceneModel(composite, layered[py : py + h, px : px + w], cells, seconds)


def _add_cell(c: Cell, src, composite, layered, pad: tuple[int, int]) -> None:
    """Both models' share of one cell, convolved over its bounding box only."""
    from scipy.signal import fftconvolve

    kh, kw = (n // 2 for n in c.kernel.shape)
    y0, y1, x0, x1 = c.rows.min(), c.rows.max() + 1, c.cols.min(), c.cols.max() + 1
    k = c.kernel[..., None]
    py, px = pad
    window = src[y0 + py - kh : y1 + py + kh, x0 + px - kw : x1 + px + kw]
    block = fftconvolve(window, k, mode="valid", axes=(0, 1))
    composite[c.rows, c.cols] = block[c.rows - y0, c.cols - x0]
    own = np.zeros((y1 - y0, x1 - x0, src.shape[2]))
    own[c.rows - y0, c.cols - x0] = src[c.rows + py, c.cols + px]
    spread = fftconvolve(own, k, mode="full", axes=(0, 1))
    layered[y0 + py - kh : y1 + py + kh, x0 + px - kw : x1 + px + kw] += spread


def window_reach_px(camera: CameraDesign, mode: str, speed_px_per_ms: float, z_min_mm: float):
    """An upper bound on any PSF's reach in a scene, before rendering it, px.

    The aperture's images span |a_i| T^2 / 4 either side of the pinhole image (coded modes),
    the motion |s| T, the defocus r; a_i and r grow with |beta|, which is largest at the
    nearest depth or at infinity (beta is monotonic in Z).
    """
    beta = beta_px_per_mm(np.array([max(z_min_mm, MIN_FOCUS_MM), 0.0]), camera)
    b = float(np.abs(beta).max())
    spread = b * camera.a_a_mm_per_ms2 * camera.T_ms**2 / 4 if mode.startswith("coded") else 0.0
    return math.ceil(spread + abs(speed_px_per_ms) * camera.T_ms + b * camera.R_mm + 2)
