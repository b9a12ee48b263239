"""The pixel grid of a kernel: its size, and its mass once the PSF is deposited on it.

Shared by the held-pattern and continuous kernels (:mod:`.analytic`) and the planar ones
(:mod:`.planar`), below both.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import ParameterError
from ..limits import check_memory

MAX_AUTO_SIZE = 2049
"""Largest kernel side chosen automatically, px; larger PSFs are truncated with a warning."""

R_DELTA_PX = 1e-3
"""Below this radius the pillbox is treated as a delta: the L1 change is < 4 r."""


MAX_LOST_FRACTION = 0.01
"""``pacam psf`` refuses a kernel that loses more than this fraction of its mass."""


class PSFTruncationWarning(UserWarning):
    """Part of the PSF's mass falls outside the kernel; the rest was renormalised.

    ``lost`` is that part, a fraction of the PSF's mass in (0, 1].
    """

    def __init__(self, message: str, lost: float = 0.0):
        super().__init__(message)
        self.lost = lost


def auto_size(lo: float, hi: float, r: float) -> int:
    half = max(abs(lo), abs(hi)) + r
    n = 2 * math.ceil(half + 0.5) + 1
    return min(n, MAX_AUTO_SIZE)


def kernel_shape(size, lo: float, hi: float, r: float) -> tuple[int, int]:
    if size is None:
        n = auto_size(lo, hi, r)
        return n, n
    h, w = (size, size) if np.isscalar(size) else size
    if int(h) != h or int(w) != w or h < 1 or w < 1:
        raise ParameterError(f"size must be a positive int or (h, w), got {size!r}")
    check_memory(f"a {h}x{w} kernel", 32.0 * h * w, "the kernel size (`size`)")
    return int(h), int(w)


def normalise(kernel: np.ndarray, expected: float) -> np.ndarray:
    got = float(kernel.sum())
    if not got > 0.0:
        raise ParameterError(
            f"no part of the PSF falls inside the {kernel.shape[0]}x{kernel.shape[1]} kernel; "
            "enlarge size"
        )
    lost = 1.0 - got / expected
    if lost > 1e-9:
        message = (
            f"{lost:.3%} of the PSF's mass lies outside the {kernel.shape[0]}x{kernel.shape[1]} "
            "kernel; the rest was renormalised"
        )
        warnings.warn(PSFTruncationWarning(message, lost), stacklevel=3)
    return kernel / got
