"""Restoration: non-blind deconvolution of coded captures and the metrics that score it.

:mod:`.deconvolve` holds the deconvolvers (:data:`METHODS`: our Wiener filter with a 1/f^2
natural-image prior fitted above the noise, Richardson-Lucy and unsupervised Wiener from
scikit-image, and optional BM3D deblurring); :mod:`.sparse` the hyper-Laplacian and
total-variation priors (``hl``, ``tv``). All use the same tapered reflect padding and
transfer functions, from :mod:`.fourier`, a leaf below them; :mod:`.noise` holds the noise a
deconvolver assumes (a white sigma, known or estimated, or the sensor's Poisson-Gaussian model);
:mod:`.metrics` holds PSNR, SSIM, shift-aligned PSNR and the fits of rendered PSFs (centroid,
the image acceleration of Eq. 18, the defocus disc of Eq. 12). Images are float (H, W) or
(H, W, C), PSFs (h, w) or (h, w, C) in px. The dispatcher ``deconvolve`` is not re-exported
here, because its name would hide the :mod:`.deconvolve` module: use
``pacam_render.restore.deconvolve.deconvolve``.
"""

from .deconvolve import (
    METHODS,
    bm3d_deblur,
    oracle_wiener,
    richardson_lucy,
    unsupervised_wiener,
    wiener,
)
from .metrics import (
    MAX_SHIFT_PX,
    aligned_psnr,
    best_shift_px,
    crop,
    fit_acceleration,
    fit_disc_radius,
    kernel_centroid,
    psnr,
    psnr_batch,
    rel_l1,
    ssim,
)
from .noise import NoiseModel, estimate_noise_sigma
from .sparse import sparse_deconvolve
from .splitting import shrink

__all__ = [
    "MAX_SHIFT_PX",
    "METHODS",
    "NoiseModel",
    "aligned_psnr",
    "best_shift_px",
    "bm3d_deblur",
    "crop",
    "estimate_noise_sigma",
    "fit_acceleration",
    "fit_disc_radius",
    "kernel_centroid",
    "oracle_wiener",
    "psnr",
    "psnr_batch",
    "rel_l1",
    "richardson_lucy",
    "shrink",
    "sparse_deconvolve",
    "ssim",
    "unsupervised_wiener",
    "wiener",
]
