"""Image and kernel metrics, in one place: PSNR, SSIM, aligned PSNR and shift search, relative
L1, and the centroid, acceleration (Eq. 18) and disc (Eq. 12) fits of rendered PSFs.

Images are float arrays with white = 1 unless a ``data_range`` says otherwise; kernels sum to 1
and are registered with their origin at the centre pixel (h//2, w//2).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft as sfft

from ..errors import ParameterError, check_positive

MAX_SHIFT_PX = 12
"""Aligned PSNR searches whole-pixel horizontal shifts within +-MAX_SHIFT_PX: a motion-invariant
PSF moves each object by -s^2 / (2 a_i) (Eq. 2 with the square completed)."""


def psnr(estimate, truth, data_range: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB."""
    mse = float(np.mean((np.asarray(estimate, float) - np.asarray(truth, float)) ** 2))
    return float("inf") if mse == 0 else 10.0 * np.log10(data_range**2 / mse)


def psnr_batch(est: np.ndarray, truth: np.ndarray, margin_px: int = 0) -> np.ndarray:
    """PSNR (dB, peak 1) per image of (N, H, W) stacks, on columns [margin, W - margin)."""
    m = int(margin_px)
    W = truth.shape[-1]
    if 2 * m >= W:
        raise ParameterError(f"margin_px = {m} leaves no columns of a {W}-px image")
    d = est[..., m : W - m] - truth[..., m : W - m]
    mse = np.mean(d * d, axis=(-2, -1))
    return 10.0 * np.log10(1.0 / np.maximum(mse, 1e-30))


def _parabola_peak(c: np.ndarray) -> float:
    """Sub-pixel argmax of a periodic 1-D sequence, as a signed shift."""
    j = int(np.argmax(c))
    left, mid, right = c[j - 1], c[j], c[(j + 1) % c.size]
    curv = left - 2 * mid + right
    dx = j + (0.5 * (left - right) / curv if curv < 0 else 0.0)
    return float(dx - c.size if dx > c.size / 2 else dx)


def best_shift_px(est_spectra: np.ndarray, truth_spectra: np.ndarray, width: int) -> np.ndarray:
    """Per image, the horizontal shift of the estimate that best matches the truth, px.

    The zero-vertical-shift cross-correlation is a 1-D inverse FFT of the column sums of
    X_est X_truth^*: one cheap transform per image.
    """
    P = (est_spectra * truth_spectra.conj()).sum(axis=-2)
    c = sfft.irfft(P, n=width, axis=-1)
    return np.array([_parabola_peak(ci) for ci in c])


def crop(img: np.ndarray, frac) -> np.ndarray:
    h, w = img.shape[:2]
    r0, r1, c0, c1 = frac
    return img[int(r0 * h) : int(r1 * h), int(c0 * w) : int(c1 * w)]


def aligned_psnr(est: np.ndarray, ref: np.ndarray, frac) -> float:
    """Best PSNR of a crop over whole-pixel horizontal shifts of the estimate."""
    h, w = ref.shape[:2]
    r0, r1, c0, c1 = frac
    rows = slice(int(r0 * h), int(r1 * h))
    a, b = max(int(c0 * w), MAX_SHIFT_PX), min(int(c1 * w), w - MAX_SHIFT_PX)
    target = ref[rows, a:b]
    return max(
        psnr(est[rows, a + d : b + d], target, 1.0) for d in range(-MAX_SHIFT_PX, MAX_SHIFT_PX + 1)
    )


def ssim(est: np.ndarray, ref: np.ndarray) -> float:
    from skimage.metrics import structural_similarity

    return float(
        structural_similarity(
            np.clip(est, 0, 1), np.clip(ref, 0, 1), channel_axis=-1, data_range=1.0
        )
    )


def kernel_centroid(kernel: np.ndarray) -> tuple[float, float]:
    """(u, v) centroid in px from the kernel origin (centre of pixel (h//2, w//2))."""
    k = np.asarray(kernel, dtype=np.float64)
    s = k.sum()
    if not s > 0:
        return math.nan, math.nan
    h, w = k.shape
    u = np.arange(w) - w // 2
    v = np.arange(h) - h // 2
    return float(k.sum(axis=0) @ u / s), float(k.sum(axis=1) @ v / s)


def fit_acceleration(t_ms, centroid_px, mass=None) -> float:
    """Image acceleration (px/ms^2): 2 x the t^2 coefficient of a parabola through the
    centroids of the windows that received light."""
    t = np.asarray(t_ms, dtype=float)
    c = np.asarray(centroid_px, dtype=float)
    ok = np.isfinite(c) & (np.ones_like(t, bool) if mass is None else np.asarray(mass) > 0)
    if ok.sum() < 3:
        return math.nan
    return float(2.0 * np.polyfit(t[ok], c[ok], 2)[0])


def fit_disc_radius(kernel: np.ndarray, r_guess: float) -> float:
    """Radius (px) of the pixel-integrated pillbox centred on the kernel origin that best fits
    ``kernel`` (least squares), searched in [r_guess / 2, 2 r_guess] within the kernel."""
    from scipy.optimize import minimize_scalar

    from ..psf.analytic import pillbox_psf

    k = np.asarray(kernel, dtype=float)
    k = k / k.sum()
    r0 = check_positive("r_guess", r_guess, "px")
    h, w = k.shape
    hi = min(2.0 * r0, 0.5 * min(h, w) - 0.5)  # a larger disc would leave the kernel
    if hi <= 0.5 * r0:
        raise ParameterError(f"kernel {h}x{w} is too small for a disc of radius ~{r0:g} px")

    def cost(r: float) -> float:
        return float(((pillbox_psf(r, size=(h, w)) - k) ** 2).sum())

    res = minimize_scalar(
        cost, bounds=(0.5 * r0, hi), method="bounded", options={"xatol": 1e-6 * r0}
    )
    return float(res.x)


def rel_l1(a: np.ndarray, b: np.ndarray) -> float:
    """L1 distance of two kernels that each sum to 1 (0 equal, 2 disjoint)."""
    return float(np.abs(np.asarray(a, float) - np.asarray(b, float)).sum())
