"""How far the simulator's defocus + diffraction is from the exact Fourier-optics PSF.

The analytic model (:mod:`.diffraction`) and a capture post-process convolve the geometric
defocus pillbox (Eq. 13, radius r = |beta| R) with the opening's Fraunhofer kernel. The exact
incoherent PSF of a defocused disc is |FT(P exp(i psi rho^2))|^2 with the defocus phase whose
geometric blur radius is r (:mod:`pacam_render.wave.defocus`). :func:`combination_error`
measures the gap as an L1 distance between normalised, pixel-integrated kernels:

- ``l1_simulator``: the discrete combination :func:`~.analytic.pillbox_psf` convolved with
  the pixel-integrated Fraunhofer kernel (:func:`~.diffraction.with_diffraction`, which counts
  the pixel's box twice; ``design_psf(..., diffraction_nm=...)`` did so before 0.3.0);
- ``l1_continuous``: the same combination done exactly (pillbox x circular MTF in the
  Fourier domain): the physics approximation alone, and what the rays and
  :func:`~.diffraction.diffracted_kernel` compute (the pixel's box once);
- ``l1_geometric``: the pillbox alone (diffraction left out, today's default).

The table for r = 0 to 4 px at F9.85 is in ``benchmarks/RESULTS.md`` ("Defocus +
diffraction", ``benchmarks/bench_diffraction.py``) and held by ``tests/psf/test_diffraction.py``.
"""

from __future__ import annotations

import time

import numpy as np

from ..wave.defocus import defocus_kernel, w020_mm
from ..wave.fraunhofer import fraunhofer_kernel
from ..wave.pupil import DiscPupil
from ..wave.scale import DiffractionScale
from .analytic import pillbox_psf
from .diffraction import convolve_kernels, crop_centred

COMPARISON_SIZE = 81
"""Side of the kernels compared, px: at F9.85 it holds all but 0.4 % of the light."""


def _l1(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a / a.sum() - b / b.sum()).sum())


def combination_error(
    radius_mm: float, r_px: float, scale: DiffractionScale, size: int = COMPARISON_SIZE
) -> dict:
    """The L1 gaps of the defocus + diffraction combinations to the exact PSF (module doc).

    Parameters
    ----------
    radius_mm : float
        The disc opening's radius on the LCoS, mm (F-number D / 2R, :mod:`~pacam_render.wave.
        scale`).
    r_px : float
        The geometric defocus radius, px.
    scale : DiffractionScale
    size : int
        Odd side of the compared kernels, px.

    Returns
    -------
    dict
        ``r_px``, ``w020_waves``, ``l1_simulator``, ``l1_continuous``, ``l1_geometric``,
        ``lost`` (the exact kernel's light outside the window) and ``seconds`` (the exact
        kernel's time).

    Examples
    --------
    >>> s = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * 0.01362)
    >>> e = combination_error(145.5 * 0.01362, 0.0, s, size=41)
    >>> e["l1_simulator"] < 1e-12, round(e["l1_geometric"], 2)
    (True, 0.71)
    """
    disc = DiscPupil(radius_mm)
    t0 = time.perf_counter()
    exact = defocus_kernel(disc, r_px, scale, size, max_lost=0.5)
    seconds = time.perf_counter() - t0
    continuous = defocus_kernel(disc, r_px, scale, size, max_lost=0.5, exact=False).kernel
    airy = fraunhofer_kernel(disc, scale, size, max_lost=0.5).kernel
    pill = pillbox_psf(r_px)
    simulator = crop_centred(convolve_kernels(pill, airy), (size, size))
    geometric = crop_centred(pill, (size, size))
    return {
        "r_px": float(r_px),
        "w020_waves": w020_mm(r_px, scale.f_number(radius_mm), scale.pixel_pitch_mm)
        / scale.wavelength_mm,
        "l1_simulator": _l1(simulator, exact.kernel),
        "l1_continuous": _l1(continuous, exact.kernel),
        "l1_geometric": _l1(geometric, exact.kernel),
        "lost": exact.lost,
        "seconds": seconds,
    }
