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
from ..psf.analytic import pillbox_psf

MAX_SHIFT_PX = 12
"""Aligned PSNR searches whole-pixel horizontal shifts within +-MAX_SHIFT_PX: a motion-invariant
PSF moves each object by -s^2 / (2 a_i) (Eq. 2 with the square completed)."""


def shift_search_px(width_px: int) -> int:
    """The alignment search for a sensor ``width_px`` wide, px: the train set's near train moves
    by -s^2 / (2 a_i) = 25 px at the prototype's full 1280 px, so +-32 px there, in proportion
    below, and at least 4."""
    return max(4, round(32 * width_px / 1280))


def psnr(estimate, truth, data_range: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB.

    Parameters
    ----------
    estimate : array_like
        The image to score.
    truth : array_like
        The reference image, same shape.
    data_range : float, optional
        The peak (white) value, in the images' units.

    Returns
    -------
    psnr : float
        10 log10(data_range^2 / MSE), dB, with MSE the mean of (estimate - truth)^2 over every
        element; ``inf`` when the two are equal.

    Examples
    --------
    >>> import numpy as np
    >>> round(psnr(np.full((8, 8), 0.51), np.full((8, 8), 0.5)), 9)  # MSE 1e-4 of white
    40.0
    """
    mse = float(np.mean((np.asarray(estimate, float) - np.asarray(truth, float)) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(data_range**2 / mse))


def psnr_batch(est: np.ndarray, truth: np.ndarray, margin_px: int = 0) -> np.ndarray:
    """PSNR (dB, peak 1) per image of (N, H, W) stacks, on columns [margin, W - margin).

    Parameters
    ----------
    est : ndarray
        Estimates, shape (N, H, W), white = 1.
    truth : ndarray
        The references, same shape.
    margin_px : int, optional
        Columns left out at each side, px.

    Returns
    -------
    psnr : ndarray of float
        10 log10(1 / MSE) per image, dB, shape (N,); the MSE is floored at 1e-30 (300 dB).

    Raises
    ------
    ParameterError
        If 2 ``margin_px`` >= W, which leaves no columns.
    """
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

    Parameters
    ----------
    est_spectra : ndarray of complex
        ``scipy.fft.rfft2`` of the estimates over their last two axes, shape (N, H, W // 2 + 1).
    truth_spectra : ndarray of complex
        The same for the truths.
    width : int
        W, the images' width, px.

    Returns
    -------
    shift : ndarray of float
        One signed, sub-pixel shift d per image, px, within about +-W/2: est(y, x + d) best
        matches truth(y, x), i.e. the estimate lies d px to the right of the truth.

    Notes
    -----
    The circular cross-correlation c(d) = sum_{y, x} est(y, x + d) truth(y, x) is the inverse
    real FFT, over f_x, of sum_{f_y} X_est(f) X_truth^*(f). Its peak is refined by a parabola
    through the peak sample and its two neighbours (left at the whole pixel when they do not
    curve downwards).
    """
    P = (est_spectra * truth_spectra.conj()).sum(axis=-2)
    c = sfft.irfft(P, n=width, axis=-1)
    return np.array([_parabola_peak(ci) for ci in c])


def crop(img: np.ndarray, frac) -> np.ndarray:
    """The part of an image between fractions of its height and width.

    Parameters
    ----------
    img : ndarray
        Image, (H, W) or (H, W, C).
    frac : tuple of float
        (r0, r1, c0, c1): rows [r0 H, r1 H) and columns [c0 W, c1 W), fractions in [0, 1].

    Returns
    -------
    ndarray
        ``img[int(r0 H):int(r1 H), int(c0 W):int(c1 W)]`` (a view).
    """
    h, w = img.shape[:2]
    r0, r1, c0, c1 = frac
    return img[int(r0 * h) : int(r1 * h), int(c0 * w) : int(c1 * w)]


def aligned_psnr(est: np.ndarray, ref: np.ndarray, frac, max_shift_px: int = MAX_SHIFT_PX) -> float:
    """Best PSNR of a crop over whole-pixel horizontal shifts of the estimate.

    A motion-invariant PSF moves each object by -s^2 / (2 a_i) px (Eq. 2 with the square
    completed), so the estimate is compared with the reference at every horizontal shift d in
    [-MAX_SHIFT_PX, MAX_SHIFT_PX] and the best PSNR is kept.

    Parameters
    ----------
    est : ndarray
        The estimate, (H, W) or (H, W, C), white = 1.
    ref : ndarray
        The reference, same shape.
    frac : tuple of float
        (r0, r1, c0, c1): the crop, as fractions of the height and width (see :func:`crop`).
        Its columns are kept at least ``max_shift_px`` inside the image, so that every shifted
        window exists.
    max_shift_px : int, optional
        The largest shift tried, px (default :data:`MAX_SHIFT_PX`; at the prototype's full
        1280-px scale the trains move up to 25 px).

    Returns
    -------
    float
        max over d of PSNR(est[rows, a + d : b + d], ref[rows, a : b]), dB, peak 1, with
        a = max(int(c0 W), max_shift_px) and b = min(int(c1 W), W - max_shift_px).
    """
    h, w = ref.shape[:2]
    r0, r1, c0, c1 = frac
    m = int(max_shift_px)
    rows = slice(int(r0 * h), int(r1 * h))
    a, b = max(int(c0 * w), m), min(int(c1 * w), w - m)
    target = ref[rows, a:b]
    return max(psnr(est[rows, a + d : b + d], target, 1.0) for d in range(-m, m + 1))


def ssim(est: np.ndarray, ref: np.ndarray) -> float:
    """Structural similarity (scikit-image) of an estimate and a reference, both clipped to [0, 1].

    Parameters
    ----------
    est : ndarray
        The estimate, (H, W, C) with white = 1, the last axis the channel axis; or (H, W) grey.
    ref : ndarray
        The reference, same shape.

    Returns
    -------
    float
        The mean SSIM over the image and the channels (1 for identical images).

    Notes
    -----
    :func:`skimage.metrics.structural_similarity` with ``channel_axis=-1`` (none for a grey
    image: its columns are not channels) and ``data_range=1.0``, on ``np.clip(est, 0, 1)`` and
    ``np.clip(ref, 0, 1)``.
    """
    from skimage.metrics import structural_similarity

    axis = -1 if np.ndim(est) == 3 else None
    return float(
        structural_similarity(
            np.clip(est, 0, 1), np.clip(ref, 0, 1), channel_axis=axis, data_range=1.0
        )
    )


def kernel_centroid(kernel: np.ndarray) -> tuple[float, float]:
    """(u, v) centroid in px from the kernel origin (centre of pixel (h//2, w//2)).

    Parameters
    ----------
    kernel : array_like
        2-D kernel (h, w); it need not be normalised.

    Returns
    -------
    u : float
        Horizontal centroid (along the columns, + to the right), px; NaN if the sum is not > 0.
    v : float
        Vertical centroid (along the rows, + downwards), px; NaN if the sum is not > 0.

    Notes
    -----
    u = sum_{y, x} k(y, x) (x - w//2) / sum k and v = sum_{y, x} k(y, x) (y - h//2) / sum k.
    """
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
    centroids of the windows that received light.

    Parameters
    ----------
    t_ms : array_like
        The windows' times (e.g. their mid-times), ms; any origin.
    centroid_px : array_like
        Each window's centroid along the motion, px; NaN for a window without light.
    mass : array_like, optional
        Each window's light; only windows with mass > 0 (and a finite centroid) are fitted.

    Returns
    -------
    a_i : float
        The image acceleration, px/ms^2; NaN with fewer than 3 usable windows.

    Notes
    -----
    A least-squares fit of c(t) = c0 + c1 t + c2 t^2. The image of a point moves as
    x(t) = x0 + s t + a_i t^2 / 2 (Eq. 2), so a_i = 2 c2, to compare with Eq. 18's
    a_i = beta a_a.
    """
    t = np.asarray(t_ms, dtype=float)
    c = np.asarray(centroid_px, dtype=float)
    ok = np.isfinite(c) & (np.ones_like(t, bool) if mass is None else np.asarray(mass) > 0)
    if ok.sum() < 3:
        return math.nan
    return float(2.0 * np.polyfit(t[ok], c[ok], 2)[0])


def fit_disc_radius(kernel: np.ndarray, r_guess: float) -> float:
    """Radius (px) of the pixel-integrated pillbox centred on the kernel origin that best fits
    ``kernel`` (least squares), searched in [r_guess / 2, 2 r_guess] within the kernel.

    Parameters
    ----------
    kernel : array_like
        2-D kernel (h, w), origin at the centre pixel (h//2, w//2); normalised to unit sum here.
    r_guess : float
        Expected radius, px, > 0: e.g. the defocus radius r = |beta| R (Eq. 12).

    Returns
    -------
    r : float
        The radius, px, of the pillbox (Eq. 13, :func:`~pacam_render.psf.analytic.pillbox_psf`)
        that minimises sum (pillbox_r - kernel)^2, within
        [r_guess / 2, min(2 r_guess, min(h, w) / 2 - 0.5)] (a larger disc would leave the
        kernel).

    Raises
    ------
    ParameterError
        If ``r_guess`` is not a finite number > 0, or the kernel is too small for the search
        (min(h, w) / 2 - 0.5 <= r_guess / 2).

    Notes
    -----
    Bounded scalar minimisation (:func:`scipy.optimize.minimize_scalar`), ``xatol``
    1e-6 r_guess.
    """
    from scipy.optimize import minimize_scalar

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
    """L1 distance of two kernels that each sum to 1 (0 equal, 2 disjoint).

    Parameters
    ----------
    a : array_like
        A non-negative kernel that sums to 1 (not checked).
    b : array_like
        Another, same shape.

    Returns
    -------
    float
        sum |a - b|, in [0, 2] for such kernels.
    """
    return float(np.abs(np.asarray(a, float) - np.asarray(b, float)).sum())
