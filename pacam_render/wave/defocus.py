"""Defocus with diffraction: the exact Fourier-optics PSF of a defocused disc, and the
geometric-optics combination (a pillbox convolved with the Airy pattern) it is compared with.

Defocus is a quadratic wavefront W(rho) = W020 rho^2 over the opening (rho = r / R, Hopkins
1955; Goodman, *Introduction to Fourier Optics*, 3rd ed., Sec. 6.4.2, Eq. 6-40). A ray through
pupil radius rho lands at a transverse offset (z / a) dW/drho from the chief ray, with z / a =
2N (Welford, *Aberrations of Optical Systems*, Sec. 6.3), so the geometric blur circle has
radius

    r = 2N x 2 W020 = 4 N W020,        i.e.   W020 = r p / (4 N)   [mm, r in px],

and the pupil's phase at its edge is psi = 2 pi W020 / lambda = pi r / (2 lambda N / p). At
F9.85 and 550 nm (lambda N / p = 0.840 px) a blur radius of r = 2 px is W020 = 0.60 waves,
r = 4 px is 1.19 waves.

The exact OTF of the defocused disc is its autocorrelation. Two discs of radius 1 a lag s
apart (s = 2 nu / nu_c in [0, 2]) overlap in a lens in which the phase difference is linear,
2 psi s x, so the integral over x is closed and (substituting y = sin t) one smooth integral
remains (Hopkins 1955, Proc. R. Soc. A 231, 91, Eq. 18; Goodman Eq. 6-41):

    H(s) = (4 / pi) int_0^{acos(s/2)} (cos t - s/2) sinc(b (cos t - s/2) / pi) cos t dt,

with b = 2 psi s. It is evaluated by Gauss-Legendre quadrature with 32 + 2 ceil(psi) nodes:
the phase varies by at most psi over the interval, so the quadrature is exact to rounding
(doubling the nodes changes the kernel by < 1e-13, ``tests/wave/test_defocus.py``). At
psi = 0 it is the circular MTF. The geometric combination's OTF is the circular MTF times the
pillbox's 2 J1(2 pi r nu) / (2 pi r nu).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from .fraunhofer import DEFAULT_MAX_LOST, DiffractionKernel, kernel_from_otf
from .otf import OTF, radial_otf, tail_px
from .pupil import DiscPupil
from .reference import circular_mtf, jinc
from .scale import DiffractionScale

MAX_DEFOCUS_PX = 64.0
"""Largest blur radius for the exact kernel, px: beyond it the kernel outgrows a few hundred
px and geometric optics is accurate anyway."""


def _check_r(r_px: float) -> float:
    r = check_finite("r_px", r_px)
    if not 0.0 <= r <= MAX_DEFOCUS_PX:
        raise ParameterError(f"r_px must be in [0, {MAX_DEFOCUS_PX:g}] px, got {r_px!r}")
    return r


def w020_mm(r_px: float, f_number: float, pixel_pitch_mm: float) -> float:
    """The defocus coefficient W020 = r p / (4 N), mm, whose geometric blur radius is r px.

    Examples
    --------
    The prototype's r = 2 px at F9.85 is 0.60 waves at 550 nm:

    >>> round(w020_mm(2.0, 9.85, 0.00645) / 550e-6, 3)
    0.595
    """
    r = _check_r(r_px)
    N = check_positive("f_number", f_number)
    return r * check_positive("pixel_pitch_mm", pixel_pitch_mm, "mm") / (4.0 * N)


def edge_phase(r_px: float, lambda_n_px: float) -> float:
    """psi = 2 pi W020 / lambda = pi r / (2 lambda N / p), radians: the defocus phase at the
    opening's edge."""
    return math.pi * _check_r(r_px) / (2.0 * check_positive("lambda_n_px", lambda_n_px, "px"))


def hopkins_otf(rho, lambda_n_px: float, psi: float, nodes: int | None = None) -> np.ndarray:
    """The exact OTF of a disc with defocus phase psi rho^2 (module docstring).

    Parameters
    ----------
    rho : array_like
        |nu|, cycles/px.
    lambda_n_px : float
        lambda N / p of the disc, px (the cut-off is 1 / lambda_n_px).
    psi : float
        Edge phase, radians (:func:`edge_phase`).
    nodes : int, optional
        Gauss-Legendre nodes; default 32 + 2 ceil(psi).
    """
    psi = check_finite("psi", psi)
    n = int(nodes) if nodes is not None else 32 + 2 * math.ceil(abs(psi))
    g, w = np.polynomial.legendre.leggauss(n)
    rho = np.asarray(rho, dtype=float)
    s = np.clip(2.0 * np.abs(rho).ravel() * lambda_n_px, 0.0, 2.0)
    out = np.zeros_like(s)
    for i in range(0, s.size, 8192):  # bounded memory
        si = s[i : i + 8192, None]
        tm = np.arccos(0.5 * si)
        t = 0.5 * tm * (g[None, :] + 1.0)
        u = np.cos(t) - 0.5 * si
        f = u * np.sinc(2.0 * psi * si * u / np.pi) * np.cos(t)
        out[i : i + 8192] = (4.0 / np.pi) * (0.5 * tm[:, 0]) * (f @ w)
    return out.reshape(rho.shape)


def _unique_radial(fn):
    """``fn`` evaluated once per distinct radius of a tensor grid."""

    def f(rho):
        u, inv = np.unique(rho, return_inverse=True)
        return fn(u)[inv].reshape(rho.shape)

    return f


def defocused_disc_otf(pupil: DiscPupil, r_px: float, scale: DiffractionScale, nodes=None):
    """The exact OTF of ``pupil`` defocused to a geometric blur radius of r px."""
    ln = scale.lambda_n_px(pupil.radius_mm)
    psi = edge_phase(r_px, ln)
    tail = tail_px(pupil.edge_mm, pupil.energy_mm2, scale)
    fn = _unique_radial(lambda rho: hopkins_otf(rho, ln, psi, nodes))
    return radial_otf(fn, 1.0 / ln, tail)


def pillbox_otf(rho, r_px: float) -> np.ndarray:
    """The transfer function of a uniform disc of radius r px, 2 J1(2 pi r nu) / (2 pi r nu)."""
    return jinc(2.0 * math.pi * _check_r(r_px) * np.asarray(rho, dtype=float))


def geometric_otf(pupil: DiscPupil, r_px: float, scale: DiffractionScale) -> OTF:
    """The geometric combination's OTF: the circular MTF times the pillbox of radius r px."""
    ln = scale.lambda_n_px(pupil.radius_mm)
    r = _check_r(r_px)
    tail = tail_px(pupil.edge_mm, pupil.energy_mm2, scale)
    fn = _unique_radial(lambda rho: circular_mtf(rho, ln) * pillbox_otf(rho, r))
    return radial_otf(fn, 1.0 / ln, tail)


def defocus_kernel(
    pupil: DiscPupil,
    r_px: float,
    scale: DiffractionScale,
    size: int | None = None,
    max_lost: float = DEFAULT_MAX_LOST,
    exact: bool = True,
    sampling: str = "pixel",
) -> DiffractionKernel:
    """The pixel-integrated PSF of a disc opening defocused to a geometric blur radius r px.

    Parameters
    ----------
    pupil : DiscPupil
    r_px : float
        Geometric blur radius |beta| R (Eq. 12), px, in [0, 64].
    scale : DiffractionScale
    size, max_lost, sampling
        As for :func:`~pacam_render.wave.fraunhofer.kernel_from_otf`.
    exact : bool
        True: the Fourier-optics PSF |FT(P exp(i psi rho^2))|^2 (Hopkins's OTF). False: the
        geometric combination, the pillbox of radius r convolved with the Airy pattern, both
        continuous (the approximation the simulator makes, before its own discretisation).

    Returns
    -------
    DiffractionKernel

    Examples
    --------
    At F9.85 and 550 nm the prototype's r = 2 px (0.6 waves): the exact PSF keeps 2.5 times
    the geometric combination's peak.

    >>> s = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * 0.01362)
    >>> disc = DiscPupil(145.5 * 0.01362)
    >>> e = defocus_kernel(disc, 2.0, s, size=41, max_lost=0.05).kernel
    >>> g = defocus_kernel(disc, 2.0, s, size=41, max_lost=0.05, exact=False).kernel
    >>> round(float(e[20, 20] / g[20, 20]), 2)
    2.49
    """
    if not isinstance(pupil, DiscPupil):
        raise ParameterError(f"pupil must be a DiscPupil, got {type(pupil).__name__}")
    otf = (defocused_disc_otf if exact else geometric_otf)(pupil, r_px, scale)
    return kernel_from_otf(otf, size, max_lost, sampling)
