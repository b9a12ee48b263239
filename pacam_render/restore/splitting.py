"""The sparse-prior solver: half-quadratic splitting on the prior, ADMM on a weighted data term.

It minimises, over the padded image x (channels c, pixels i),

    E(x) = sum_ci w_ci / 2 ((k_c * x_c)_ci - y_ci)^2 + sum_i phi((d_x x)_i) + phi((d_y x)_i)

with phi(g) = |g|^alpha per channel, or (sum_c g_c^2)^(alpha / 2) when the channels share one
prior (edges fall at the same place in every colour). Two auxiliary variables split it:

- g = d x, with a penalty beta / 2 ||g - d x||^2 and no dual: half-quadratic splitting, beta
  raised geometrically from :data:`BETA_START` to a last beta over the iterations (by default
  Krishnan & Fergus 2009's schedule, 6 steps of 2 sqrt(2) to :data:`BETA_STOP`; the sparse
  methods stop higher, :data:`.sparse.SCHEDULE`). Stopping at a finite beta leaves a
  Huber-like prior, which scores higher than the exact minimiser of E: on 4 photographs at
  sigma 0.01, running ADMM on g to convergence lost 0.6 dB;
- z = k * x, with a scaled dual u (ADMM, Afonso et al. 2010's SALSA form), so that the per-pixel
  weights w stay out of the x-step. The z-step is a per-pixel weighted mean, the g-step a
  shrinkage (:func:`shrink`, :func:`group_shrink`) and the x-step exact in the Fourier domain.

With uniform weights this is the plain half-quadratic splitting of the hyper-Laplacian paper.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from .fourier import WORKERS, psf_to_otf

BETA_START, BETA_STOP = 1.0, 256.0
"""The prior's penalty at the first and the last iteration (Krishnan & Fergus 2009); the sparse
methods stop higher (:data:`.sparse.SCHEDULE`)."""
ITERATIONS = 1 + round(math.log(BETA_STOP / BETA_START) / math.log(2.0 * math.sqrt(2.0)))
"""6: beta rises by 2 sqrt(2) per iteration. More iterations approach the exact minimiser of E
and score lower (``benchmarks/bench_deconvolve.py``, PSNR against iterations)."""


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


def group_shrink(v: np.ndarray, alpha: float, beta: float, joint: bool) -> np.ndarray:
    """argmin_g phi(g) + beta / 2 ||g - v||^2 for v of shape (2, C, H, W).

    Per channel it is :func:`shrink`. Jointly, phi depends on the colour vector's norm only, so
    the minimiser keeps v's direction and shrinks its norm as a scalar.
    """
    if not joint or v.shape[1] == 1:
        return shrink(v, alpha, beta)
    norm = np.sqrt(np.sum(v * v, axis=1, keepdims=True))
    out = shrink(norm, alpha, beta)
    return v * np.divide(out, norm, out=np.zeros_like(norm), where=norm > 0)


def gradient_otfs(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Transfer functions of the forward differences d_x and d_y on a grid of ``shape``."""
    dx = np.array([[0.0, -1.0, 1.0]])
    return psf_to_otf(dx, shape), psf_to_otf(dx.T, shape)


@dataclass
class Problem:
    """A weighted deconvolution problem on the padded grid, channels first.

    Attributes
    ----------
    y : ndarray
        (C, Hp, Wp) data, the pad included.
    weight : ndarray
        (C, Hp, Wp) data weights w (lambda / variance), 0 where a sample is left out.
    otf : ndarray
        (C, Hp, Wp // 2 + 1) transfer functions (:func:`~.fourier.psf_to_otf`).
    alpha : float
        The prior's exponent in (0, 1].
    joint : bool
        One prior on the colour vector of each gradient, or one per channel.
    """

    y: np.ndarray
    weight: np.ndarray
    otf: np.ndarray
    alpha: float
    joint: bool

    @property
    def shape(self) -> tuple[int, int]:
        return self.y.shape[1:]

    def fft(self, x: np.ndarray) -> np.ndarray:
        return sfft.rfft2(x, workers=WORKERS)

    def ifft(self, X: np.ndarray) -> np.ndarray:
        return sfft.irfft2(X, s=self.shape, workers=WORKERS)

    def gradients(self, X: np.ndarray) -> np.ndarray:
        """d x as (2, C, Hp, Wp), from x's spectrum."""
        dx, dy = gradient_otfs(self.shape)
        return np.stack([self.ifft(dx * X), self.ifft(dy * X)])

    def objective(self, x: np.ndarray) -> float:
        """E(x) for a padded estimate x, (C, Hp, Wp)."""
        X = self.fft(x)
        r = self.ifft(self.otf * X) - self.y
        g = self.gradients(X)
        phi = np.sqrt(np.sum(g * g, axis=1)) if self.joint else np.abs(g)
        return float(0.5 * np.sum(self.weight * r * r) + np.sum(phi**self.alpha))


def solve(
    p: Problem,
    x0: np.ndarray,
    iterations: int = ITERATIONS,
    callback: Callable[[int, np.ndarray], None] | None = None,
    beta_stop: float = BETA_STOP,
) -> np.ndarray:
    """Minimise from ``x0`` (C, Hp, Wp); ``callback(i, x)`` sees each iterate. Returns x.

    The prior's penalty rises geometrically from :data:`BETA_START` to ``beta_stop`` over the
    ``iterations``. The data split's penalty rho is the mean weight, so with uniform weights
    z - u = y after every step and this is exactly half-quadratic splitting.
    """
    dx, dy = gradient_otfs(p.shape)
    h2 = (p.otf * p.otf.conj()).real
    d2 = (dx * dx.conj()).real + (dy * dy.conj()).real
    observed = p.weight[p.weight > 0]
    rho = float(np.mean(observed)) if observed.size else 1.0
    wy = p.weight * p.y
    X, u = p.fft(x0), np.zeros_like(x0)
    for i, beta in enumerate(np.geomspace(BETA_START, beta_stop, iterations)):
        kx = p.ifft(p.otf * X)
        z = (wy + rho * (kx + u)) / (p.weight + rho)
        u += kx - z
        G = p.fft(group_shrink(p.gradients(X), p.alpha, beta, p.joint))
        num = rho * p.otf.conj() * p.fft(z - u) + beta * (dx.conj() * G[0] + dy.conj() * G[1])
        X = num / (rho * h2 + beta * d2)
        if callback is not None:
            callback(i, p.ifft(X))
    return p.ifft(X)
