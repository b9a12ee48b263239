"""Fraunhofer diffraction of a disc opening in the rays: each camera ray's film position is
jittered by a draw from the opening's Airy pattern (issue 36, item 1).

A ray through film position x carries the radiance seen from x + d, d drawn from the PSF: the
pixel then integrates the geometric image convolved with the continuous Airy pattern, so a
point in focus renders as the *pixel-integrated* Airy pattern and an edge's MTF is multiplied
by the circular pupil's diffraction-limited MTF. Defocus, motion and occlusion stay those of
the rays. Every disc opening of a schedule diffracts alike wherever it sits (shift theorem), so
one pattern serves the whole exposure; its scale follows the opening's radius R (``configure``
recomputes it): lambda N px, N = D / 2R, D = 2 F_min R_max the pupil's distance.

Sampling (host tables here, the draw in :mod:`.aperture_camera`). The radial variable
v = pi r / (lambda N) has the density p(v) = 4 J1(v)^2 / v on [0, v_max], the same for every
wavelength, tabulated at :data:`TABLE_SIZE` nodes (Mitsuba's ``ContinuousDistribution``
evaluates it for the channel weights) and drawn by an inverse-CDF table of
:data:`INVERSE_SIZE` quantiles (two gathers; a binary search over the nodes cost 4x more per
ray); the drawn distribution's L1 gap to the Airy pattern is :func:`inverse_table`'s.
v_max leaves out :data:`MAX_LOST` of the light (1 - EE(v) = J0^2 + J1^2 ~ 2 / (pi v)),
renormalised away as the post-process kernels do. In an RGB variant a channel c is picked
uniformly and r = v lambda N_c / pi; each channel is then weighted by its own density over
the mixture's, q_c(r) / mean_c' q_c'(r) with q_c = p(pi r / lambda N_c) / lambda N_c (at most
3): an unbiased draw of every channel's pattern at its own wavelength, in one ray.

Random numbers: the channel, v and the angle come from a TEA hash of the ray's film and lens
samples (Mitsuba's RGB and mono integrators pass a wavelength sample of 0, and no other sample
dimension is free), so the same seed gives the same image; the hash's draws are independent of
the sampler's strata, so the jitter adds plain Monte Carlo noise, counted in ``mc_sigma``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..errors import ParameterError, check_positive

MAX_LOST = 0.002
"""Light of the Airy pattern beyond v_max, left out and renormalised (as the kernels'
``DEFAULT_MAX_LOST``)."""
TABLE_SIZE = 16385
"""Nodes of the radial table."""


def encircled_energy(v) -> np.ndarray:
    """Rayleigh's closed form: the Airy pattern's light inside v = pi r / (lambda N)."""
    from scipy.special import j0, j1

    v = np.asarray(v, float)
    return 1.0 - j0(v) ** 2 - j1(v) ** 2


def v_max_for(max_lost: float = MAX_LOST) -> float:
    """The smallest table end whose left-out light is at most ``max_lost``: 1 - EE decays as
    2 / (pi v) with ripples, so search from the asymptote outward."""
    v = 2.0 / (math.pi * max_lost)
    grid = np.linspace(0.5 * v, 2.0 * v, 20001)
    lost = 1.0 - encircled_energy(grid)
    # the last crossing: beyond it the ripples never again leave out more than max_lost
    above = np.flatnonzero(lost > max_lost)
    return float(grid[above[-1] + 1]) if above.size else float(grid[0])


@lru_cache(maxsize=4)
def radial_table(max_lost: float = MAX_LOST, n: int = TABLE_SIZE):
    """(v_max, pdf values at n equally spaced nodes, the light left out, the table's L1 gap
    to the exact radial density): the Airy pattern's radial density 4 J1(v)^2 / v."""
    from scipy.special import j1

    v_max = v_max_for(max_lost)
    v = np.linspace(0.0, v_max, n)
    pdf = np.empty_like(v)
    pdf[0] = 0.0
    pdf[1:] = 4.0 * j1(v[1:]) ** 2 / v[1:]
    fine = np.linspace(0.0, v_max, 8 * (n - 1) + 1)[1:]
    exact = 4.0 * j1(fine) ** 2 / fine
    lin = np.interp(fine, v, pdf)
    h = fine[1] - fine[0]
    lost = float(1.0 - encircled_energy(v_max))
    l1 = float(np.sum(np.abs(lin - exact)) * h / max(1.0 - lost, 1e-300))
    return v_max, pdf.astype(np.float32), lost, l1


INVERSE_SIZE = 262144
"""Intervals of the inverse-CDF table the rays draw v from (O(1): two gathers, no search;
1 MB). Its gap to the Airy pattern, 0.001 L1, is in the far rings (v > 100, r > 27 px at F9.85),
whose oscillations a quantile interval there spans."""


@lru_cache(maxsize=4)
def inverse_table(max_lost: float = MAX_LOST, m: int = INVERSE_SIZE, bin_v: float = 0.05):
    """(v at the m + 1 quantiles j / m of the radial table's distribution, float32; the L1 gap
    of the distribution drawn to the exact Airy pattern's, over bins of ``bin_v`` in v).

    A draw is v = lerp(table[j], table[j + 1], frac(u m)), uniform between two quantiles. The
    gap is measured over bins of 0.05 in v (1/60 of the first dark ring, 0.013 px at F9.85):
    below that, float32 nodes a few ulp apart make the drawn density grainy without moving
    any light by a visible distance. The record states it (``airy_table_l1``)."""
    v_max, pdf, lost, _ = radial_table(max_lost)
    v = np.linspace(0.0, v_max, pdf.size)
    p = pdf.astype(float)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(v))])
    cdf /= cdf[-1]
    keep = np.concatenate([[True], np.diff(cdf) > 0])  # a strictly rising CDF to invert
    u = np.linspace(0.0, 1.0, m + 1)
    q = np.interp(u, cdf[keep], v[keep]).astype(np.float32)
    edges = np.arange(0.0, v_max + bin_v, bin_v)
    drawn = np.interp(edges, q.astype(float), u)  # the drawn CDF (float32 nodes as drawn)
    exact = np.minimum(encircled_energy(edges) / (1.0 - lost), 1.0)
    l1 = float(np.sum(np.abs(np.diff(drawn) - np.diff(exact))))
    return q, l1


def parse_wavelengths(value) -> tuple[float, ...]:
    """``diffraction_wavelengths``: nm, ``"611, 549, 464"`` or one value, each in [300, 1100]."""
    if isinstance(value, (int, float)):
        parts = [float(value)]
    else:
        try:
            parts = [float(p) for p in str(value).replace(";", ",").split(",") if p.strip()]
        except ValueError:
            parts = []
    if not parts or not all(300.0 <= p <= 1100.0 for p in parts):
        raise ParameterError(
            "diffraction_wavelengths must be one or three wavelengths in nm, each in "
            f"[300, 1100], e.g. '611, 549, 464'; got {value!r}"
        )
    return tuple(parts)


def sensor_properties(design, wavelengths_nm, pixel_pitch_mm: float) -> dict:
    """The plugin's load-time properties that put diffraction in the rays of a camera of
    ``design`` (its pupil at D = 2 F_min R_max), one wavelength (nm) per colour channel, on
    film pixels of ``pixel_pitch_mm``: the one recipe for captures and PSF renders."""
    return {
        "diffraction_wavelengths": ", ".join(f"{w:g}" for w in wavelengths_nm),
        "pupil_distance": 2.0 * float(design.F_min) * float(design.R_max_mm),
        "pixel_pitch": float(pixel_pitch_mm),
    }


class RayDiffractionSpec:
    """The host side: wavelengths, the pupil's distance and the pixel pitch (mm), checked.

    Parameters
    ----------
    wavelengths_nm : tuple of float
        One per colour channel of the variant (3 for RGB, 1 for mono).
    pupil_distance_mm : float
        D = 2 F_min R_max, the pupil's distance from the image.
    pixel_pitch_mm : float
        The film's pixel pitch (a binned capture's larger one).
    """

    def __init__(self, wavelengths_nm, pupil_distance_mm: float, pixel_pitch_mm: float):
        self.wavelengths_nm = parse_wavelengths(wavelengths_nm)
        self.pupil_distance_mm = check_positive("pupil_distance", pupil_distance_mm, "mm")
        self.pixel_pitch_mm = check_positive("pixel_pitch", pixel_pitch_mm, "mm")

    def lambda_n_px(self, radius_mm: float) -> list[float]:
        """lambda N in px for each wavelength through a disc of radius R (mm)."""
        if not radius_mm > 0:
            raise ParameterError("diffraction needs an open disc: aperture_radius > 0")
        n = self.pupil_distance_mm / (2.0 * radius_mm)
        return [w * 1e-6 * n / self.pixel_pitch_mm for w in self.wavelengths_nm]


MAX_ORDER = 8
"""The grid's orders drawn on each axis: |m| <= 8 (the rest renormalised away, stated)."""


def grid_orders(fill_factor: float, max_order: int = MAX_ORDER) -> tuple[np.ndarray, float]:
    """The LCoS pixel grid's diffraction orders on one axis: P(m) for m = -M..M and the light
    beyond, for square pixel apertures of linear fill factor f (amplitude transmission a comb of
    width f x pitch): order m carries f sinc^2(m f) of the transmitted light (the Fourier
    series of the comb, Parseval: they sum to 1; returned renormalised over |m| <= M).
    f = 1: every order but 0 is dark.

    Examples
    --------
    >>> p, lost = grid_orders(0.8)
    >>> round(float(p[MAX_ORDER]), 3), round(float(p[MAX_ORDER + 1] / p[MAX_ORDER]), 4)
    (0.811, 0.0547)
    >>> grid_orders(1.0)[0][MAX_ORDER], grid_orders(1.0)[1]
    (1.0, 0.0)
    """
    f = float(fill_factor)
    if not 0.0 < f <= 1.0:
        raise ParameterError(f"lcos_fill_factor must be in (0, 1], got {fill_factor!r}")
    m = np.arange(-max_order, max_order + 1)
    p = f * np.sinc(m * f) ** 2
    p[(np.abs(m * f - np.round(m * f)) < 1e-12) & (m != 0)] = 0.0  # sinc's zeros, exactly
    lost = max(1.0 - float(p.sum()), 0.0)
    return p / p.sum(), lost


def order_px(wavelength_nm: float, pupil_distance_mm: float, lcos_pitch_mm: float,
             pixel_pitch_mm: float) -> float:  # fmt: skip
    """The first order's offset on the film, px: lambda D / pitch of the LCoS (the grating in
    the pupil, D from the image), about 244 px at 550 nm for the prototype."""
    return wavelength_nm * 1e-6 * pupil_distance_mm / lcos_pitch_mm / pixel_pitch_mm
