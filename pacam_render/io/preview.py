"""sRGB previews of linear images (colour-science's sRGB encoding), written atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .outputs import atomic_save


def srgb8(linear: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """8-bit sRGB of a linear image; ``exposure`` scales it (default: 99.5th percentile -> 1)."""
    import colour

    x = np.asarray(linear, dtype=float)
    if not np.all(np.isfinite(x)):
        raise ParameterError("the image to preview contains NaN or infinite values")
    if exposure is None:
        hi = float(np.percentile(x, 99.5)) if x.size else 1.0
        exposure = 1.0 / hi if hi > 0 else 1.0
    enc = colour.cctf_encoding(np.clip(x * exposure, 0.0, 1.0), function="sRGB")
    return np.round(enc * 255.0).astype(np.uint8)


def write_png(path: str | os.PathLike, image8: np.ndarray, force: bool = False) -> Path:
    import imageio.v3 as iio  # installed with scikit-image

    def save(tmp: str) -> None:
        iio.imwrite(tmp, image8, extension=".png")

    return atomic_save(path, save, force)
