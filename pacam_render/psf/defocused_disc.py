"""The defocused disc's PSF as a pupil integral: the light of a point seen through a disc
opening whose wavefront has the quadratic defocus W020 rho^2 (issue 45).

    I(v; psi) = |U(v; psi)|^2,   U(v; psi) = 2 int_0^1 exp(i psi rho^2) J0(v rho) rho d rho,

in v = pi r / (lambda N) (r and lambda N in the same units), with the edge phase
psi = 2 pi W020 / lambda = pi r_geo / (2 lambda N) for a geometric blur radius r_geo
(:mod:`pacam_render.wave.defocus`). At psi = 0 it is the Airy pattern (2 J1(v) / v)^2; by
Parseval int_0^inf I v dv = 2 for every psi. U is a Gauss-Legendre sum over rho with
:data:`NODES` nodes (more than 9 per period of J0 out to v = 370).
:mod:`pacam_render.wave.defocus` gives the same PSF's OTF in closed form (Hopkins); the rays
(:mod:`pacam_render.render.ray_defocus`) and the exact kernels (:mod:`.exact_defocus`) use
this one.
"""

from __future__ import annotations

import math

import numpy as np

PSI_MAX = 8.0 * math.pi
"""The largest edge phase the exact PSF is used at (the rays' table holds it,
:mod:`pacam_render.render.ray_defocus`): W020 = 4 waves (r = 16 lambda N px); beyond, the
geometric disc convolved with the Airy pattern is used, where the two meet."""

NODES = 640
"""Gauss-Legendre nodes over the pupil radius."""


def amplitude(v, psi: float, nodes: int = NODES) -> np.ndarray:
    """U(v; psi) (module docstring) at radii ``v``, complex."""
    from scipy.special import j0

    x, w = np.polynomial.legendre.leggauss(nodes)
    rho = 0.5 * (x + 1.0)
    wr = w * rho * np.exp(1j * psi * rho * rho)  # 2 x (d rho = dx / 2) x rho x phase
    return j0(np.outer(np.asarray(v, float), rho)) @ wr


def radial_density(r_px, psi: float, lambda_n_px: float) -> np.ndarray:
    """The exact PSF's density per unit area at film radius ``r_px`` (1/px^2), from the
    pupil integral (not the table): I / (int I dA)."""
    v = math.pi * np.asarray(r_px, float) / lambda_n_px
    scale = math.pi / lambda_n_px  # dv / dr
    # int I 2 pi r dr = 2 pi / scale^2 int I v dv = 4 pi / scale^2
    return np.abs(amplitude(v, psi)) ** 2 * scale**2 / (4.0 * math.pi)
