"""The deconvolvers' shared ground: input checks, tapered padding and the PSF's transfer function.

Every deconvolver of :mod:`pacam_render.restore` (Wiener, the scikit-image ones, BM3D and the
sparse priors of :mod:`.sparse` and :mod:`.splitting`) handles the boundary the same way: the
image is reflect-padded by the PSF's extent and the pad is tapered with a raised cosine towards
the image mean, so the padded image is periodic and continuous and the circular FFT does not ring
at the borders. The PSF's origin is its centre pixel (h//2, w//2). This module is a leaf of the
subpackage (as scikit-image keeps ``uft.py``): it imports nothing else of it.
"""

from __future__ import annotations

import os

import numpy as np
import scipy.fft as sfft

from ..errors import ParameterError

WORKERS = os.cpu_count() or 1
"""Threads for scipy's FFTs."""


# --- validation -------------------------------------------------------------------------------
def check_psf(psf, image_shape: tuple[int, ...]) -> np.ndarray:
    """Validate a PSF against an image and return it normalised to unit mass, as float64.

    Parameters
    ----------
    psf : array_like
        The point-spread function on the image's pixel grid (px): 2-D (h, w), shared by all
        channels, or 3-D (h, w, C), one kernel per channel. Finite and non-negative.
    image_shape : tuple of int
        Shape of the image it will deconvolve, (H, W) or (H, W, C).

    Returns
    -------
    psf : ndarray of float64
        The PSF divided by its sum (per channel for an (h, w, C) PSF), so each kernel sums to 1.

    Raises
    ------
    ParameterError
        If the PSF is not 2-D or 3-D, contains NaN or infinite values, has a negative value, has
        zero total mass (in any channel), is larger than half the image in either direction, or is
        3-D with a channel count other than the image's (1 for an (H, W) image).
    """
    k = np.asarray(psf, dtype=float)
    if k.ndim not in (2, 3):
        raise ParameterError(f"psf must be 2-D (h, w) or (h, w, C), got shape {k.shape}")
    if not np.all(np.isfinite(k)):
        raise ParameterError("psf contains NaN or infinite values")
    if k.min() < 0:
        raise ParameterError(f"psf must be non-negative, min is {k.min():g}")
    sums = k.sum(axis=(0, 1))
    if np.any(sums <= 0):
        raise ParameterError("psf is all zero: it must have positive total mass")
    if 2 * k.shape[0] > image_shape[0] + 1 or 2 * k.shape[1] > image_shape[1] + 1:
        raise ParameterError(
            f"psf of {k.shape[0]}x{k.shape[1]} px is larger than half the "
            f"{image_shape[0]}x{image_shape[1]} px image: the borders, which the blur mixes "
            "with the unseen scene outside, would be most of it; deblur a larger image (or "
            "crop the PSF's empty margins)"
        )
    if k.ndim == 3:
        channels = image_shape[2] if len(image_shape) == 3 else 1
        if k.shape[2] != channels:
            raise ParameterError(
                f"psf has {k.shape[2]} channels but the image has {channels}: mismatched channels"
            )
    return k / sums


def check_image(image) -> np.ndarray:
    """Validate an image and return it as a finite float64 array.

    Parameters
    ----------
    image : array_like
        Image of shape (H, W) or (H, W, C), on any linear scale.

    Returns
    -------
    image : ndarray of float64
        The image, same shape.

    Raises
    ------
    ParameterError
        If the image is not 2-D or 3-D, or contains NaN or infinite values.
    """
    y = np.asarray(image, dtype=float)
    if y.ndim not in (2, 3):
        raise ParameterError(f"image must be (H, W) or (H, W, C), got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ParameterError("image contains NaN or infinite values")
    return y


# --- boundaries ----------------------------------------------------------------------------------
def pad_width(psf_shape: tuple[int, ...]) -> tuple[int, int]:
    """Rows and columns of padding for a PSF: its full extent, so the blur never wraps.

    Parameters
    ----------
    psf_shape : tuple of int
        Shape of the PSF, (h, w) or (h, w, C), px.

    Returns
    -------
    pad : tuple of int
        (h, w): the rows and columns of padding, px (see :func:`taper_pad`).
    """
    return int(psf_shape[0]), int(psf_shape[1])


def _ramp(n: int, head: int, tail: int) -> np.ndarray:
    """1 inside, raised-cosine fall to 0 over ``head`` and ``tail`` samples at the ends."""
    w = np.ones(n)
    for p, sl in ((head, slice(0, head)), (tail, slice(n - tail, n))):
        if p > 0:
            t = 0.5 - 0.5 * np.cos(np.pi * (np.arange(p) + 0.5) / p)
            w[sl] = t if sl.start == 0 else t[::-1]
    return w


def taper_pad(image2d: np.ndarray, pad: tuple[int, int]) -> tuple[np.ndarray, tuple[slice, slice]]:
    """Reflect-pad to an FFT-friendly size, fade the pad to the image mean with a raised cosine.

    The image gets ``pad`` rows above and columns to the left, and at least as many below and to
    the right: up to the next size that :func:`scipy.fft.next_fast_len` finds fast for a real
    FFT. The pad is reflected (``symmetric`` instead when the image is one pixel thick or the pad
    is not smaller than the image's shorter side), then faded towards the image mean, so that
    the padded image is periodic and continuous and the circular FFT does not ring at the
    borders.

    Parameters
    ----------
    image2d : ndarray
        One channel, shape (H, W).
    pad : tuple of int
        (py, px): rows and columns of padding on each side, px; usually :func:`pad_width`.

    Returns
    -------
    padded : ndarray
        The padded, tapered image, shape (Hp, Wp) with
        Hp = ``next_fast_len(H + 2 py, real=True)`` and Wp likewise.
    keep : tuple of slice
        (rows, columns) that crop the original (H, W) region back out of ``padded``.

    Notes
    -----
    With m the image mean and w(y, x) = w_y(y) w_x(x) a separable window,
    padded = m + (reflected - m) w. Each 1-D window is 1 over the image and, over a pad of p
    samples, rises from the outer edge as 0.5 - 0.5 cos(pi (k + 1/2) / p), k = 0 .. p - 1.
    """
    h, w = image2d.shape
    py, px = pad
    H = sfft.next_fast_len(h + 2 * py, real=True)
    W = sfft.next_fast_len(w + 2 * px, real=True)
    widths = ((py, H - h - py), (px, W - w - px))
    mode = "reflect" if min(h, w) > 1 and max(py, px) < min(h, w) else "symmetric"
    out = np.pad(image2d, widths, mode=mode)
    mean = image2d.mean()
    win = np.outer(_ramp(H, *widths[0]), _ramp(W, *widths[1]))
    return mean + (out - mean) * win, (slice(py, py + h), slice(px, px + w))


# --- transfer function ------------------------------------------------------------------------
def psf_to_otf(psf2d: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Real-FFT transfer function (OTF) of a centred PSF on a grid of ``shape``.

    Parameters
    ----------
    psf2d : ndarray
        2-D PSF (h, w) whose origin is its centre pixel (h//2, w//2); at most ``shape``.
    shape : tuple of int
        (H, W) of the (padded) image grid, px.

    Returns
    -------
    otf : ndarray of complex128
        ``scipy.fft.rfft2`` of the PSF zero-padded to ``shape`` and rolled circularly so that
        its centre pixel sits at (0, 0); shape (H, W // 2 + 1).

    Notes
    -----
    With the origin at (0, 0), multiplying an image spectrum by the OTF convolves the image with
    the PSF (circularly) without shifting it.
    """
    big = np.zeros(shape)
    h, w = psf2d.shape
    big[:h, :w] = psf2d
    big = np.roll(big, (-(h // 2), -(w // 2)), axis=(0, 1))
    return sfft.rfft2(big, workers=WORKERS)
