"""Sparse-prior deconvolution: hyper-Laplacian (Krishnan & Fergus 2009) and total variation.

Both minimise, per channel,

    E(x) = lambda / 2 ||k * x - y||^2 + sum_i |(d_x x)_i|^alpha + |(d_y x)_i|^alpha

with alpha = 1 for total variation and alpha < 1 for the heavy-tailed gradients of natural
images, by half-quadratic splitting: auxiliary gradients w with a penalty beta / 2 ||w - d x||^2,
beta raised from 1 to 256 by 2 sqrt(2) per stage (Krishnan & Fergus's schedule). Each stage
solves the w-step pixel by pixel (:func:`shrink`) and the x-step exactly in the Fourier domain,
on the same reflect-padded, tapered image as Wiener (:func:`~.deconvolve.taper_pad`).

The data weight follows the noise: lambda = :data:`LAMBDA_SCALE` / sigma^2, with sigma the
known noise (a capture's record) or the wavelet estimate, on the image scaled so that its
99.5th percentile is 1 (the prior is not scale-free); the scale was chosen on
``benchmarks/bench_sparse.py``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft as sfft

from ..errors import ParameterError
from .deconvolve import (
    SIGMA_FLOOR,
    WORKERS,
    _check_sigma,
    _per_channel,
    check_image,
    check_psf,
    estimate_noise_sigma,
    pad_width,
    psf_to_otf,
    taper_pad,
)

HL_ALPHA = 2.0 / 3.0
"""The hyper-Laplacian's exponent (Krishnan & Fergus 2009 use 1/2 and 2/3)."""
LAMBDA_SCALE = {"hl": 0.3, "tv": 0.2}
"""lambda sigma^2 per method, chosen on benchmarks/bench_sparse.py: the best of 0.1, 0.3, 1
over two photographs at sigma = 0.01 and 0.03 (hl's optimum moves from 0.3 to 1 as the noise
grows, tv's stays between 0.1 and 0.3)."""
BETA_START, BETA_STOP, BETA_RATE = 1.0, 256.0, 2.0 * math.sqrt(2.0)


def shrink(v: np.ndarray, alpha: float, beta: float, iterations: int = 10) -> np.ndarray:
    """argmin_w |w|^alpha + beta / 2 (w - v)^2, element-wise.

    Parameters
    ----------
    v : ndarray
    alpha : float
        In (0, 1]; 1 is soft thresholding.
    beta : float
        The penalty weight, > 0.
    iterations : int, optional
        Fixed-point iterations for alpha < 1 (10 reach the minimum within 1e-12 in energy
        on a grid of v and beta; 4 left 5e-6 near the threshold).

    Returns
    -------
    ndarray
        Same shape as ``v``.

    Notes
    -----
    For alpha < 1, generalised soft thresholding (Zuo et al. 2013) with lam = 1 / beta:
    w = 0 below tau = (2 lam (1 - alpha))^(1 / (2 - alpha))
    + lam alpha (2 lam (1 - alpha))^((alpha - 1) / (2 - alpha)), and above it the fixed point
    of |w| = |v| - lam alpha |w|^(alpha - 1), started at |v|.
    """
    a = np.abs(v)
    lam = 1.0 / beta
    if alpha == 1.0:
        return np.sign(v) * np.maximum(a - lam, 0.0)
    base = 2.0 * lam * (1.0 - alpha)
    tau = base ** (1.0 / (2.0 - alpha)) + lam * alpha * base ** ((alpha - 1.0) / (2.0 - alpha))
    big = a > tau
    w = a[big]
    for _ in range(iterations):
        w = a[big] - lam * alpha * w ** (alpha - 1.0)
    out = np.zeros_like(a)
    out[big] = w
    return np.sign(v) * out


def _gradient_otfs(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    dx = np.array([[0.0, -1.0, 1.0]])
    return psf_to_otf(dx, shape), psf_to_otf(dx.T, shape)


def _hqs2d(y: np.ndarray, k: np.ndarray, lam: float, alpha: float) -> np.ndarray:
    yp, keep = taper_pad(y, pad_width(k.shape))
    shape = yp.shape
    H = psf_to_otf(k, shape)
    Dx, Dy = _gradient_otfs(shape)
    data = lam * H.conj() * sfft.rfft2(yp, workers=WORKERS)
    grad2 = (Dx * Dx.conj()).real + (Dy * Dy.conj()).real
    h2 = lam * (H * H.conj()).real
    X = sfft.rfft2(yp, workers=WORKERS)
    beta = BETA_START
    while beta <= BETA_STOP * (1 + 1e-9):
        gx = sfft.irfft2(Dx * X, s=shape, workers=WORKERS)
        gy = sfft.irfft2(Dy * X, s=shape, workers=WORKERS)
        Wx = sfft.rfft2(shrink(gx, alpha, beta), workers=WORKERS)
        Wy = sfft.rfft2(shrink(gy, alpha, beta), workers=WORKERS)
        X = (data + beta * (Dx.conj() * Wx + Dy.conj() * Wy)) / (h2 + beta * grad2)
        beta *= BETA_RATE
    return sfft.irfft2(X, s=shape, workers=WORKERS)[keep]


def sparse_deconvolve(
    image, psf, method: str = "hl", noise_sigma: float | None = None, alpha: float | None = None
):
    """Hyper-Laplacian (``"hl"``) or total-variation (``"tv"``) deconvolution, per channel.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C), linear.
    psf : array_like
        PSF, as for :func:`~.deconvolve.wiener`.
    method : {"hl", "tv"}
    noise_sigma : float, optional
        The noise's standard deviation in the image's units; None: estimated
        (:func:`~.deconvolve.estimate_noise_sigma`). Sets lambda = LAMBDA_SCALE / sigma^2.
    alpha : float, optional
        The prior's exponent in (0, 1] (``"hl"`` only; default :data:`HL_ALPHA`).

    Returns
    -------
    ndarray of float64
        The estimate, same shape as ``image``.

    Raises
    ------
    ParameterError
        For an unknown method, an alpha outside (0, 1], a bad sigma, image or PSF.
    """
    if method not in LAMBDA_SCALE:
        raise ParameterError(f"sparse method must be 'hl' or 'tv', got {method!r}")
    a = 1.0 if method == "tv" else (HL_ALPHA if alpha is None else float(alpha))
    if not 0.0 < a <= 1.0 or (method == "tv" and alpha not in (None, 1.0)):
        raise ParameterError(f"alpha must be in (0, 1] (hl only), got {alpha!r}")
    y = check_image(image)
    k = check_psf(psf, y.shape)
    sigma = None if noise_sigma is None else _check_sigma(noise_sigma)
    if not y.any():
        return np.zeros_like(y)
    sigma = estimate_noise_sigma(y) if sigma is None else sigma
    # the prior is not scale-free (|grad x|^alpha against a squared data term): work on an image
    # whose bright end is 1, as the weight was chosen, and scale the estimate back
    scale = float(np.percentile(np.abs(y), 99.5)) or float(np.abs(y).max())
    sigma = max(sigma / scale, SIGMA_FLOOR)
    lam = LAMBDA_SCALE[method] / sigma**2
    return scale * _per_channel(y / scale, k, lambda c, kk: _hqs2d(c, kk, lam, a))
