"""Closed forms of the diffraction-limited circular pupil: the references every kernel is
checked against.

- The Airy pattern (Born & Wolf, *Principles of Optics*, 7th ed., Sec. 8.5.2, Eq. 14):
  I(r) = I0 (2 J1(v) / v)^2 with v = pi r / (lambda N), normalised here to unit volume, so
  I0 = pi / (4 (lambda N)^2). Its first zero is at 1.22 lambda N.
- The diffraction-limited MTF of a circular pupil (Goodman, *Introduction to Fourier Optics*,
  3rd ed., Eq. 6-32): H(v) = (2/pi) (acos v - v sqrt(1 - v^2)), v = nu lambda N <= 1.
- J1 itself, numpy only: the periodic trapezoid rule on Bessel's integral
  J1(x) = (1/2 pi) int_0^{2 pi} cos(t - x sin t) dt (DLMF 10.9.2; 64 nodes: its error is
  ~J_63(x), below 1e-15 for |x| <= 25) and Hankel's asymptotic series beyond (DLMF 10.17.3,
  10 terms: below 1e-15 at x = 25). Checked against scipy.special.j1 in the tests.

Lengths are in px (``lambda_n_px`` = lambda N / pixel pitch), frequencies in cycles/px.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError, check_positive

_SMALL_X = 25.0
"""Below this |x| J1 uses the trapezoid rule, above it Hankel's series."""
_NODES = 64
_HANKEL_TERMS = 10


def _j1_trapezoid(x: np.ndarray) -> np.ndarray:
    t = 2.0 * np.pi * np.arange(_NODES) / _NODES
    out = np.empty_like(x)
    for i in range(0, x.size, 65536):  # bounded memory
        xi = x[i : i + 65536, None]
        out[i : i + 65536] = np.cos(t[None, :] - xi * np.sin(t)[None, :]).mean(axis=1)
    return out


def _j1_hankel(x: np.ndarray) -> np.ndarray:
    """Hankel's expansion of J1 for large x: sqrt(2/(pi x)) (P cos chi - Q sin chi)."""
    mu = 4.0
    p = np.zeros_like(x)
    q = np.zeros_like(x)
    term = np.ones_like(x)  # a_k(1) / x^k with a_k = prod_{j<=k} (mu - (2j-1)^2) / (k! 8^k)
    for k in range(2 * _HANKEL_TERMS):
        if k > 0:
            term = term * (mu - (2 * k - 1) ** 2) / (k * 8.0 * x)
        if k % 2 == 0:
            p += (-1) ** (k // 2) * term
        else:
            q += (-1) ** (k // 2) * term
    chi = x - 0.75 * np.pi
    return np.sqrt(2.0 / (np.pi * x)) * (p * np.cos(chi) - q * np.sin(chi))


def bessel_j1(x) -> np.ndarray:
    """The Bessel function of the first kind of order 1, J1(x), to ~1e-15 absolute.

    Examples
    --------
    >>> [round(float(v), 12) + 0.0 for v in bessel_j1([0.0, 1.0, 3.8317059702075125, 40.0])]
    [0.0, 0.440050585745, 0.0, 0.126038318038]
    """
    a = np.asarray(x, dtype=float)
    flat = np.abs(a).ravel()
    out = np.empty_like(flat)
    small = flat <= _SMALL_X
    out[small] = _j1_trapezoid(flat[small])
    out[~small] = _j1_hankel(flat[~small])
    return (np.sign(a.ravel()) * out).reshape(a.shape)  # J1 is odd


def jinc(x) -> np.ndarray:
    """2 J1(x) / x, 1 at x = 0: the amplitude of a circular pupil (and the pillbox's OTF)."""
    a = np.asarray(x, dtype=float)
    out = np.ones_like(a)
    nz = np.abs(a) > 1e-8  # 2 J1(x)/x = 1 - x^2/8 + ...: below 1e-8 the error is < 1e-17
    out[nz] = 2.0 * bessel_j1(a[nz]) / a[nz]
    return out


def airy_psf(r_px, lambda_n_px: float) -> np.ndarray:
    """The Airy pattern as a density of unit volume, per px^2 (Born & Wolf 8.5.2 Eq. 14).

    Parameters
    ----------
    r_px : array_like
        Distance from the centre, px.
    lambda_n_px : float
        lambda N / pixel pitch, px.

    Examples
    --------
    >>> round(float(airy_psf(0.0, 1.0)), 6) == round(np.pi / 4, 6)
    True
    """
    ln = check_positive("lambda_n_px", lambda_n_px, "px")
    v = np.pi * np.asarray(r_px, dtype=float) / ln
    return np.pi / (4.0 * ln * ln) * jinc(v) ** 2


def circular_mtf(nu_cycles_per_px, lambda_n_px: float) -> np.ndarray:
    """The diffraction-limited MTF of a circular pupil (Goodman Eq. 6-32), 0 beyond cut-off.

    H = (2/pi) (acos v - v sqrt(1 - v^2)) with v = |nu| lambda N, nu in cycles/px.

    Examples
    --------
    The prototype's F9.85 opening at 550 nm (lambda N = 0.840 px) at Nyquist, 0.48 as
    PHYSICS.md says:

    >>> round(float(circular_mtf(0.5, 0.55e-3 * 9.85 / 6.45e-3)), 3)
    0.481
    """
    ln = check_positive("lambda_n_px", lambda_n_px, "px")
    v = np.clip(np.abs(np.asarray(nu_cycles_per_px, dtype=float)) * ln, 0.0, 1.0)
    return (2.0 / np.pi) * (np.arccos(v) - v * np.sqrt(1.0 - v * v))


def airy_kernel_quadrature(lambda_n_px: float, size: int, nodes: int = 12) -> np.ndarray:
    """The Airy pattern integrated over each pixel of a ``size`` x ``size`` grid by
    Gauss-Legendre quadrature (``nodes`` x ``nodes`` per pixel), not normalised: its sum is
    the energy inside the grid.

    An independent reference for :func:`~pacam_render.wave.fraunhofer.fraunhofer_kernel`:
    it shares no code with the Fourier path. The Airy pattern is smooth (band-limited to
    1/(lambda N) cycles/px), so the quadrature converges exponentially: 12 nodes reach ~1e-9
    L1 at lambda N >= 0.8 px.
    """
    n = int(size)
    if n < 1 or n % 2 == 0:
        raise ParameterError(f"size must be an odd integer >= 1, got {size!r}")
    if n > 1025:
        raise ParameterError(f"size must be <= 1025 for the quadrature reference, got {size!r}")
    g, w = np.polynomial.legendre.leggauss(int(nodes))
    pts = ((np.arange(n) - n // 2)[:, None] + 0.5 * g[None, :]).ravel()
    wts = np.tile(0.5 * w, n)
    out = np.empty((n, n))
    for i in range(n):  # one row of pixels at a time: bounded memory
        y = pts[i * len(g) : (i + 1) * len(g)]
        dens = airy_psf(np.hypot(y[:, None], pts[None, :]), lambda_n_px)
        row = (wts[i * len(g) : (i + 1) * len(g)] @ dens) * wts
        out[i] = row.reshape(n, len(g)).sum(axis=1)
    return out
