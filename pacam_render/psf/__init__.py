"""Analytic PSFs on the pixel grid: the paper's Eqs. 1, 13 and 14 and the baselines.

Every kernel is a normalised float64 (h, w) array, odd-sized, with its origin at the centre
pixel (h//2, w//2) where the point images at mid-exposure t = 0, each value integrated over its
pixel. :mod:`.analytic` builds Levin's motion PSF phi (Eq. 1), the pillbox psi of the defocus
radius r = |beta| R (Eqs. 12-13), the coded capture's Phi = phi * psi (Eq. 14) and its exact
16-pattern form, and the normal, short-exposure and fluttered-shutter baselines;
:func:`design_psf` picks the kernel of a capture mode from a camera design. :mod:`.trajectory`
(the time the moving point spends in each pixel) and :mod:`.pillbox` (exact disc coverage)
supply the pieces. Units: s in px/ms, a_i in px/ms^2, T and exposures in ms (the exposure is
2T, t in [-T, T]), r in px. :mod:`.bitmap` gives the exact kernel of any LCoS bitmap schedule.
"""

from .analytic import (
    MODE_TRAJECTORIES,
    coded_psf,
    design_psf,
    design_trajectory,
    discrete_coded_psf,
    flutter_psf,
    levin_psf,
    pillbox_psf,
    short_exposure_psf,
    static_psf,
)
from .bitmap import bitmap_kernel
from .grid import PSFTruncationWarning
from .robust import aligned_speed_psf, speed_robust_psf

__all__ = [
    "MODE_TRAJECTORIES",
    "PSFTruncationWarning",
    "aligned_speed_psf",
    "bitmap_kernel",
    "coded_psf",
    "design_psf",
    "design_trajectory",
    "discrete_coded_psf",
    "flutter_psf",
    "levin_psf",
    "pillbox_psf",
    "short_exposure_psf",
    "speed_robust_psf",
    "static_psf",
]
