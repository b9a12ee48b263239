"""sRGB previews of linear images, written atomically.

The sRGB encoding is IEC 61966-2-1's closed form (:func:`srgb_encode`), written here rather
than taken from colour-science: importing ``colour`` took 1.5 s of every command that writes a
preview, and the tests check the formula against colour-science's ``cctf_encoding``."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .outputs import atomic_save


def srgb8(linear: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """8-bit sRGB of a linear image; ``exposure`` scales it (default: 99.5th percentile -> 1)."""
    x = np.asarray(linear, dtype=float)
    if not np.all(np.isfinite(x)):
        raise ParameterError("the image to preview contains NaN or infinite values")
    if exposure is None:
        hi = float(np.percentile(x, 99.5)) if x.size else 1.0
        exposure = 1.0 / hi if hi > 0 else 1.0
    enc = srgb_encode(np.clip(x * exposure, 0.0, 1.0))
    return np.round(enc * 255.0).astype(np.uint8)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1): 12.92 x up to 0.0031308, else
    1.055 x^(1/2.4) - 0.055; ``linear`` in [0, 1]."""
    x = np.asarray(linear, dtype=float)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def write_png(path: str | os.PathLike, image8: np.ndarray, force: bool = False) -> Path:
    """Write an 8-bit image as a PNG, atomically.

    Parameters
    ----------
    path : path-like
        The PNG to write.
    image8 : numpy.ndarray
        uint8, (H, W) grey, (H, W, 1) grey (written as (H, W): PNG writers refuse one
        channel), or (H, W, 3) colour.
    force : bool, optional
        Overwrite an existing file.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ParameterError
        If the image is not (H, W), (H, W, 1) or (H, W, 3), or the file exists without ``force``.
    """
    import imageio.v3 as iio  # installed with scikit-image

    image8 = np.asarray(image8)
    if image8.ndim == 3 and image8.shape[2] == 1:
        image8 = image8[..., 0]
    if not (image8.ndim == 2 or (image8.ndim == 3 and image8.shape[2] == 3)):
        raise ParameterError(
            f"a PNG preview must be (H, W), (H, W, 1) or (H, W, 3), got {image8.shape}"
        )

    def save(tmp: str) -> None:
        iio.imwrite(tmp, image8, extension=".png")

    return atomic_save(path, save, force)


def psf_extent(shape: tuple[int, ...]) -> tuple[float, float, float, float]:
    """The (left, right, bottom, top) of a kernel's pixels in px from its centre pixel
    (h // 2, w // 2), x right and y down, for matplotlib's ``imshow(extent=...)``."""
    h, w = shape[:2]
    return (-(w // 2) - 0.5, w - w // 2 - 0.5, h - h // 2 - 0.5, -(h // 2) - 0.5)


def write_psf_preview(
    path: str | os.PathLike, kernel: np.ndarray, title: str = "", force: bool = False
) -> Path:
    """A PSF's PNG preview with its scale: axes in px from the centre pixel and a colour bar
    of the fraction of the point's light per px (a colour kernel is shown as its mean).

    Raises
    ------
    ParameterError
        If ``kernel`` is not 2-D or 3-D, or holds NaN or infinite values.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = np.asarray(kernel, dtype=float)
    if k.ndim not in (2, 3) or not np.all(np.isfinite(k)):
        raise ParameterError("`kernel` must be a finite 2-D (or H x W x C) PSF")
    k = k.mean(axis=2) if k.ndim == 3 else k
    h, w = k.shape
    fig, ax = plt.subplots(figsize=(6.0, float(np.clip(4.4 * h / w + 1.2, 2.2, 6.0))))
    im = ax.imshow(k, cmap="magma", interpolation="nearest", extent=psf_extent(k.shape))
    ax.set(xlabel="x (px)", ylabel="y (px)", title=title or f"PSF, {w}x{h} px")
    fig.colorbar(im, ax=ax, label="fraction of the point's light per px", shrink=0.85)
    fig.tight_layout()
    try:
        return atomic_save(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"), force)
    finally:
        plt.close(fig)
