"""Bayer colour-filter mosaic and bilinear demosaic.

A Bayer sensor measures one colour per pixel. The 2x2 tile is named by its colours in reading
order: ``"RGGB"`` has R at (row 0, col 0), G at (0, 1) and (1, 0), B at (1, 1). The tile repeats
from the top-left pixel of the image, whatever the image's size (odd sizes are allowed).

- :func:`mosaic` keeps, at each pixel, the channel its filter passes: (H, W, 3) -> (H, W).
- :func:`demosaic_bilinear` fills the two missing channels of each pixel with the mean of its
  nearest same-colour neighbours (the classic bilinear demosaic): (H, W) -> (H, W, 3). It keeps
  every measured sample exactly, reproduces constant colours exactly (edges included), and linear
  ramps exactly away from the one-pixel border. Edges use mirror padding (the pixel beyond the
  edge is the one just inside it), which keeps the colour parity of the tile, so every missing
  value is still a mean of real samples of its colour.

Values are whatever the caller works in (photons, e-, DN); both functions are linear.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError

BAYER_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")
"""Supported 2x2 tiles, named in reading order."""

_CHANNEL = {"R": 0, "G": 1, "B": 2}


def check_pattern(pattern: str) -> str:
    """Return the upper-cased pattern, or raise unless it is one of :data:`BAYER_PATTERNS`."""
    p = str(pattern).upper() if isinstance(pattern, str) else pattern
    if p not in BAYER_PATTERNS:
        raise ParameterError(f"bayer must be one of {', '.join(BAYER_PATTERNS)}, got {pattern!r}")
    return p


def tile_channels(pattern: str = "RGGB") -> np.ndarray:
    """Channel index (0=R, 1=G, 2=B) of each position in the 2x2 tile, shape (2, 2)."""
    p = check_pattern(pattern)
    return np.array([[_CHANNEL[p[0]], _CHANNEL[p[1]]], [_CHANNEL[p[2]], _CHANNEL[p[3]]]])


def channel_index(shape: tuple[int, int], pattern: str = "RGGB") -> np.ndarray:
    """Channel index of every pixel of an (H, W) mosaic, as an int8 array of that shape."""
    h, w = shape
    tile = tile_channels(pattern).astype(np.int8)
    return np.tile(tile, ((h + 1) // 2, (w + 1) // 2))[:h, :w]


def mosaic(rgb: np.ndarray, pattern: str = "RGGB") -> np.ndarray:
    """Sample an (H, W, 3) image through the colour filter array: returns (H, W), same dtype."""
    a = np.asarray(rgb)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ParameterError(f"mosaic needs an (H, W, 3) image, got shape {a.shape}")
    tile = tile_channels(pattern)
    out = np.empty(a.shape[:2], dtype=a.dtype)
    for dy in (0, 1):
        for dx in (0, 1):
            out[dy::2, dx::2] = a[dy::2, dx::2, tile[dy, dx]]
    return out


def demosaic_bilinear(raw: np.ndarray, pattern: str = "RGGB") -> np.ndarray:
    """Bilinear demosaic of an (H, W) mosaic into (H, W, 3) float32 (float64 for float64 input).

    Each missing value is the mean of the 2 (horizontal or vertical), 4 (cross) or 4 (diagonal)
    nearest samples of its colour: the 3x3 kernels [[1,2,1],[2,4,2],[1,2,1]]/4 (R, B) and
    [[0,1,0],[1,4,1],[0,1,0]]/4 (G) applied to each colour's masked plane, computed here with
    shifted slices of the mirror-padded mosaic. Needs H, W >= 2.
    """
    a = np.asarray(raw)
    if a.ndim != 2:
        raise ParameterError(f"demosaic needs an (H, W) mosaic, got shape {a.shape}")
    if min(a.shape) < 2:
        raise ParameterError(f"demosaic needs H, W >= 2 px, got shape {a.shape}")
    tile = tile_channels(pattern)
    dtype = np.float64 if a.dtype == np.float64 else np.float32
    p = np.pad(a.astype(dtype, copy=False), 1, mode="reflect")  # numpy reflect = mirror
    centre = p[1:-1, 1:-1]
    horiz = 0.5 * (p[1:-1, :-2] + p[1:-1, 2:])
    vert = 0.5 * (p[:-2, 1:-1] + p[2:, 1:-1])
    diag = 0.25 * (p[:-2, :-2] + p[:-2, 2:] + p[2:, :-2] + p[2:, 2:])
    cross = 0.5 * (horiz + vert)
    out = np.empty((*a.shape, 3), dtype=dtype)
    for dy in (0, 1):
        for dx in (0, 1):
            own = tile[dy, dx]
            for c in range(3):
                if c == own:
                    src = centre
                elif c == 1:
                    src = cross
                elif own == 1:
                    src = horiz if tile[dy, 1 - dx] == c else vert
                else:
                    src = diag
                out[dy::2, dx::2, c] = src[dy::2, dx::2]
    return out
