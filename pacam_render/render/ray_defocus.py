"""Exact paraxial defocus with diffraction in the rays: the defocused disc's PSF, drawn per
scene point by the particle tracer (issue 45, item 1).

A disc opening of radius R centred at c, in a lens defocused for a point's depth, has a pupil
phase whose quadratic part about c is W020 rho^2 (rho = |a - c| / R); its linear part is the
parallax that puts the point's image at its chief ray through c, and the constant drops out
(``../shared/PHYSICS.md``, "Defocus with diffraction"). So the light from the point lands at
that image plus an offset drawn from the defocused disc's PSF I(v; psi)
(:mod:`pacam_render.psf.defocused_disc`), v = pi |offset| / (lambda N) (lambda N in px, N the
opening's F-number), psi = pi r / (2 lambda N) for a geometric blur radius r px. The density
of v is p(v) = I v / 2.

The table is one function of (psi, v) for every opening and wavelength: rows of psi from 0 to
:data:`PSI_MAX` (4 waves: beyond it the exact PSF and the geometric disc convolved with the
Airy pattern agree, and the rays draw that), each out to the geometric edge 2 psi plus the
Airy pattern's tail (:data:`MAX_LOST` left out and renormalised away, as the Airy draw does).
A draw interpolates two rows' inverse CDFs (quantile interpolation; rows 5x closer moved a
rendered kernel by less than its Monte Carlo floor).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..psf.defocused_disc import NODES, PSI_MAX
from .ray_diffraction import MAX_LOST, v_max_for

PSI_STEP = 0.25
"""Row spacing in psi (0.04 waves)."""
V_STEP = 0.025
"""Spacing of the radial grid in v (1/150 of the Airy pattern's first dark ring)."""
QUANTILES = 16384
"""Intervals of each row's inverse-CDF table."""


def psi_rows() -> np.ndarray:
    return np.arange(0.0, PSI_MAX + 0.5 * PSI_STEP, PSI_STEP)


def v_end(psi: float, max_lost: float = MAX_LOST) -> float:
    """Where a row ends: the geometric edge 2 psi plus the Airy pattern's tail."""
    return 2.0 * psi + v_max_for(max_lost)


@lru_cache(maxsize=2)
def defocus_table(max_lost: float = MAX_LOST):
    """The rays' tables: (psi rows, v grid, density p(v) per row (rows x grid, float32, 0
    beyond the row's end), inverse CDF per row ((rows, QUANTILES + 1), float32), light left out
    per row).

    Each row's density is renormalised over [0, v_end(psi)] as drawn."""
    from scipy.special import j0

    psis = psi_rows()
    v = np.arange(0.0, v_end(psis[-1], max_lost) + V_STEP, V_STEP)
    x, w = np.polynomial.legendre.leggauss(NODES)
    rho = 0.5 * (x + 1.0)
    basis = j0(np.outer(v, rho))  # shared by every row: two real products for all rows
    phase = psis[None, :] * (rho * rho)[:, None]
    re = basis @ ((w * rho)[:, None] * np.cos(phase))
    im = basis @ ((w * rho)[:, None] * np.sin(phase))
    pdf = np.zeros((len(psis), len(v)))
    inv = np.empty((len(psis), QUANTILES + 1), np.float32)
    lost = np.empty(len(psis))
    u = np.linspace(0.0, 1.0, QUANTILES + 1)
    for i, psi in enumerate(psis):
        p = 0.5 * (re[:, i] ** 2 + im[:, i] ** 2) * v
        p[v > v_end(psi, max_lost)] = 0.0
        cdf = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * V_STEP)])
        lost[i] = max(0.0, 1.0 - cdf[-1])
        pdf[i] = p / cdf[-1]
        cdf /= cdf[-1]
        keep = np.concatenate([[True], np.diff(cdf) > 0])
        inv[i] = np.interp(u, cdf[keep], v[keep])
    return psis, v, pdf.astype(np.float32), inv, lost
