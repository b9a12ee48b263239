"""The Wiener prior's level is fitted where the kernel passes the light (``PRIOR_MIN_TRANSFER``):
a capture whose blur is not the kernel the restoration is told (objects at other depths or
speeds) must not inflate it at the told kernel's notches. Reference: the level of an image drawn
with a known 1/f^2 spectrum."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.restore import deconvolve as dm
from pacam_render.restore.fourier import psf_to_otf

N = 256


def _disc(r: float, at=(0, 0), size: int = 41) -> np.ndarray:
    y, x = np.mgrid[:size, :size] - size // 2
    return ((x - at[0]) ** 2 + (y - at[1]) ** 2 <= r * r).astype(float)


def _level(kernel_told: np.ndarray, kernel_true: np.ndarray) -> float:
    """The fitted c over the drawn image's median level, the capture blurred by ``kernel_true``
    and the fit told ``kernel_told``. The fit is a median of |Y|^2 / (|H|^2 g), and a Gaussian
    field's |Y|^2 is exponential: its median is ln 2 of its mean."""
    rng = np.random.default_rng(0)
    g = 1.0 / (dm._freq2((N, N)) + (1.0 / N) ** 2)
    c_true, sigma = 1e-3, 0.01
    X = np.sqrt(c_true * g * N * N / 2) * (rng.normal(size=g.shape) + 1j * rng.normal(size=g.shape))
    H_true = psf_to_otf(kernel_true / kernel_true.sum(), (N, N))
    y = np.fft.irfft2(X * H_true, s=(N, N)) + rng.normal(0, sigma, (N, N))
    H = psf_to_otf(kernel_told / kernel_told.sum(), (N, N))
    S = dm.prior_spectrum(np.fft.rfft2(y), np.abs(H) ** 2, (N, N), sigma)
    return float(S[0, 1] / g[0, 1]) / (c_true * np.log(2.0))


def test_the_level_through_the_true_kernel_is_the_drawn_one():
    assert _level(_disc(4), _disc(4)) == pytest.approx(1.0, rel=0.15)


def test_notches_the_blur_does_not_share_leave_the_level_near_the_truth(monkeypatch):
    """Told four openings spread in 2-D (a kernel with many notches) while the capture is one
    disc's blur: the fit stays within 1.6x of the truth; fitted at every frequency above the
    noise (the threshold off), it overstates the level several-fold."""
    spread = sum(_disc(3, at) for at in ((-9, -4), (8, -7), (-5, 9), (10, 6)))
    assert _level(spread, _disc(4)) < 1.6
    monkeypatch.setattr(dm, "PRIOR_MIN_TRANSFER", 0.0)
    assert _level(spread, _disc(4)) > 3.0
