"""Plug-and-play deconvolution: half-quadratic splitting around a pretrained CNN denoiser.

It solves, over the padded image x of each channel,

    min_x 1 / (2 sigma^2) ||k * x - y||^2 + R(x)

with the prior R known only through a denoiser (Venkatakrishnan, Bouman and Wohlberg 2013).
Half-quadratic splitting with an auxiliary z alternates, with a penalty mu_i that rises as the
denoiser's noise level sigma_i falls (Zhang, Li, Zuo, Zhang, Van Gool and Timofte 2021, DPIR):

    x_i = argmin_x ||k * x - y||^2 + rho_i ||x - z_{i-1}||^2,    rho_i = lam sigma^2 / sigma_i^2
    z_i = D(x_i; sigma_i)

The x-step is exact in the Fourier domain on the tapered, padded grid of :mod:`.fourier`; the
z-step is scico's DnCNN (Zhang et al. 2017) with a noise-level input (variant ``6N``: 6 layers,
trained on [0, 1] images at noise sigma 0 to 0.2), whose weights ship inside the scico wheel,
so nothing is downloaded. sigma_i falls geometrically from :data:`SIGMA_START` to
:data:`END_FACTOR` times the noise level over the iterations (:data:`ITERATIONS`). Each
denoiser call averages the network over :data:`ENSEMBLE` flips and quarter turns of its input
(DPIR's self-ensemble), which makes its errors less systematic, and the local mean of what
it removed is put back (:data:`MEAN_WINDOW_PX`): the network shifts flat regions. The image
is divided by its peak |y|, into the range the network was trained on, and scaled back. Not
by a percentile, as :mod:`.sparse` does: values past 1 cost 1.0 dB on a 256 px photograph
whose 99.5th percentile was 0.9. Where the noise would then be past the network's training
(:data:`SIGMA_TRAINED`), the image is divided by 5 sigma instead: on a 128 px photograph
denoised at sigma 1 and 2.4, 13.5 and 7.9 dB became 15.0 and 9.4 (hl: 12.1 and 10.7). Noise
larger than the signal's range is past what the network can do: a rendered short exposure
through the ICX285 at 10 photons/px/ms scored 4.8 dB against hl's 14.4
(docs/studies/crossover_pnp); use hl there.

Optional extra: ``pip install 'pacam_render[pnp]'`` (scico, with jax and flax; about 480 MB
installed). Colour images are restored per channel (the network is single-channel); the
channels go through it as one batch. Denoising in an orthonormal opponent space instead (the
white noise stays white) lost 3.7 to 6.2 dB on 4 ICX285 captures (benchmarks/bench_pnp.py
--only opponent): its chroma planes are centred on 0, outside the network's [0, 1] training.

References: S. V. Venkatakrishnan, C. A. Bouman and B. Wohlberg, "Plug-and-play priors for model
based reconstruction", IEEE GlobalSIP 2013. K. Zhang, Y. Li, W. Zuo, L. Zhang, L. Van Gool and
R. Timofte, "Plug-and-play image restoration with deep denoiser prior", IEEE TPAMI 44(10), 2021
(DPIR). K. Zhang, W. Zuo, Y. Chen, D. Meng and L. Zhang, "Beyond a Gaussian denoiser: residual
learning of deep CNN for image denoising", IEEE TIP 26(7), 2017 (DnCNN).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
from scipy.ndimage import gaussian_filter

from ..errors import ParameterError
from .fourier import WORKERS, check_image, check_psf, pad_width, psf_to_otf, taper_pad
from .noise import check_sigma, estimate_noise_sigma

VARIANT = "6N"
"""scico's DnCNN variant: 6 layers with a noise-level input. On 4 grey photographs (256 px,
the prototype's coded kernel, sigma 0.01) it scored 30.40 dB in 4.2 s per image; 17N, 3.3x
slower, diverged at :data:`LAMBDA` (18.6 dB; benchmarks/bench_pnp.py --variants, 8 steps)."""
SIGMA_START = 49.0 / 255.0
"""The denoiser's noise level at the first iteration, on the [0, 1] scale (DPIR's 49/255)."""
SIGMA_TRAINED = 0.2
"""The top of the noise levels the network was trained on; it is never asked for more."""
SIGMA_MIN = 1.0 / 1000.0
"""The smallest noise level used, on the [0, 1] scale: a noiseless input would make rho 0 and
the x-step an inverse filter, which divides by the kernel's spectral zeros."""
LAMBDA = 0.35
"""lam in rho_i = lam sigma^2 / sigma_i^2: at the defaults, on the astronaut, brick, camera and
chelsea photographs, 0.2, 0.35, 0.5 and 1 scored 30.52, 30.86, 30.64 and 29.90 dB
(benchmarks/bench_pnp.py; 0.35 was also the best at 8 steps without the ensemble)."""
ITERATIONS = 5
"""Steps of the schedule. DPIR takes 8, but this small network's errors accumulate at low
sigma: on the 4 photographs of :data:`LAMBDA`, 2, 3, 4, 5, 6, 8 and 12 steps scored 30.21,
30.69, 30.82, 30.86, 30.87, 30.83 and 30.67 dB, in proportional time (benchmarks/bench_pnp.py).
Before :data:`END_FACTOR`, :data:`ENSEMBLE` and :data:`MEAN_WINDOW_PX`, 24 steps lost 7.9 dB."""
END_FACTOR = 3.0
"""The schedule ends at this multiple of the noise level, not at it: the x-step's output
carries the noise amplified by the deblur, more than sigma, and a denoiser told sigma leaves
it. On the camera, brick, Hubble, rocket and clock photographs (benchmarks/bench_pnp.py
--sweep), the other knobs at their defaults, ending at 1, 2, 3 and 4 sigma scored
33.68, 33.84, 33.99 and 33.99 dB."""
MEAN_WINDOW_PX = 4.0
"""sigma, px, of the Gaussian over which the denoiser's residual x - D(x) is averaged and put
back into D(x). The residual should be noise, whose mean over the window is near 0; the
network's is not on flat regions (0.1 at level 0.19 comes out 29 % low, 1.0 at 0.1 1.8 % high,
the first step's level). On the photographs of :data:`END_FACTOR`, 0 (not put back), 2, 4
and 8 px scored 33.87, 33.82, 33.99 and 33.97 dB; 2 px loses the clock 1.5 dB."""
ENSEMBLES = (1, 2, 4, 8)
"""The allowed self-ensemble sizes: the first n of the 8 flips and quarter turns of a square."""
ENSEMBLE = 4
"""Denoiser calls averaged per step, over flips and quarter turns (DPIR's x8 self-ensemble,
cut to 4). On the photographs of :data:`END_FACTOR`, 1, 2, 4 and 8 scored 33.65, 33.83,
33.99 and 34.03 dB, in 1, 1.3, 2.5 and 5.5 times the seconds of 1."""
INSTALL = "pip install 'pacam_render[pnp]'"


@lru_cache(maxsize=2)
def _network(variant: str):
    """The jitted DnCNN of ``variant``: f(planes (C, H, W), sigma) -> denoised planes."""
    try:
        import jax
        import jax.numpy as jnp
        from scico.denoiser import DnCNN
    except ImportError as exc:
        raise ParameterError(
            f"method 'pnp' needs the optional scico package (its DnCNN denoiser): {INSTALL}"
        ) from exc
    net = DnCNN(variant)
    apply = jax.jit(lambda v, a: net.model.apply(v, a, train=False, mutable=False))

    def denoise(planes: np.ndarray, sigma: float) -> np.ndarray:
        a = jnp.asarray(planes, dtype=jnp.float32)[..., None]
        a = jnp.concatenate([a, jnp.full_like(a, sigma)], axis=-1)
        return np.asarray(apply(net.variables, a), dtype=float)[..., 0]

    return denoise


def schedule(sigma: float, iterations: int, start: float = SIGMA_START) -> np.ndarray:
    """The denoiser's noise levels: geometric from ``start`` down to :data:`END_FACTOR` times
    ``sigma``, on the [0, 1] scale.

    The end is not raised past :data:`SIGMA_TRAINED` (nor lowered below ``sigma``): a level
    the network is not asked for would only weaken the x-step's penalty rho (at sigma 0.2 the
    result fell from 15.8 to -5.2 dB). An end above ``start`` is used throughout. Levels
    above :data:`SIGMA_TRAINED` are capped by :func:`pnp_deconvolve`, not here.
    """
    end = max(sigma, min(END_FACTOR * sigma, SIGMA_TRAINED))
    return np.geomspace(max(start, end), end, iterations)


def self_ensemble(denoise: Callable, planes: np.ndarray, level: float, n: int) -> np.ndarray:
    """The mean of ``denoise`` over the first ``n`` of the 8 flips and quarter turns.

    Each transformed copy is denoised and turned back before the mean, so a denoiser that
    commutes with the transforms gives its own output (a property the tests check).
    """
    out = np.zeros_like(planes)
    for k in range(n):
        turn = np.rot90(planes[..., ::-1] if k % 2 else planes, k // 2, axes=(1, 2))
        back = np.rot90(denoise(np.ascontiguousarray(turn), level), -(k // 2), axes=(1, 2))
        out += back[..., ::-1] if k % 2 else back
    return out / n


def pnp_deconvolve(
    image,
    psf,
    noise_sigma: float | None = None,
    *,
    iterations: int = ITERATIONS,
    lam: float = LAMBDA,
    ensemble: int = ENSEMBLE,
    callback: Callable[[int, np.ndarray], None] | None = None,
) -> np.ndarray:
    """Plug-and-play deconvolution with a pretrained DnCNN denoiser (module doc).

    Parameters
    ----------
    image : array_like
        Blurred, noisy, linear image: (H, W) or (H, W, C), any size (the network's receptive
        field, 13 px for 6 layers, need not fit: the grid is padded).
    psf : array_like
        (h, w) or (h, w, C) PSF, px, as for :func:`~.deconvolve.wiener`.
    noise_sigma : float, optional
        White noise's standard deviation, image units: the capture's known one; None:
        estimated (:func:`~.noise.estimate_noise_sigma`). Below :data:`SIGMA_MIN` of the
        image's scale it is used as that.
    iterations : int, optional
        Steps of the schedule, >= 1 (:data:`ITERATIONS`).
    lam : float, optional
        The penalty's scale, > 0 (:data:`LAMBDA`); larger trusts the denoiser more.
    ensemble : {1, 2, 4, 8}, optional
        Flips and quarter turns averaged per denoiser call (:data:`ENSEMBLE`); the cost
        grows in proportion.
    callback : callable, optional
        ``callback(i, estimate)`` after each iteration, with the cropped estimate.

    Returns
    -------
    ndarray of float64
        The estimate, same shape as ``image``.

    Raises
    ------
    ParameterError
        If scico is not installed, or for a bad image, PSF, ``noise_sigma``, ``iterations``,
        ``lam`` or ``ensemble``; before any work.

    Notes
    -----
    With s = max(max |y|, sigma / 0.2), y and sigma are divided by s; each channel is padded
    (:func:`~.fourier.taper_pad`) and, for i = 1 .. n, with sigma_i from :func:`schedule` and
    rho_i = lam sigma^2 / sigma_i^2,

        x_i = F^-1[(H* Y + rho_i Z_{i-1}) / (|H|^2 + rho_i)],   z_i = D(x_i; min(sigma_i, 0.2))

    starting from z_0 = y, with D averaged over ``ensemble`` flips and turns
    (:func:`self_ensemble`) and the residual's local mean G * (x_i - D) put back (G a
    Gaussian of :data:`MEAN_WINDOW_PX`). The estimate is s z_n, cropped. An all-zero image
    gives zeros.

    The references are in the module doc.
    """
    y, k, sigma = _checked(image, psf, noise_sigma, iterations, lam, ensemble)
    denoise = _network(VARIANT)
    if not y.any():
        return np.zeros_like(y)
    planes, scale, sigma = _network_scale(y, sigma)
    z, keep, h2, hy = _data_term(planes, k)

    def crop(x: np.ndarray) -> np.ndarray:
        out = scale * x[(slice(None), *keep)]
        return out[0] if y.ndim == 2 else np.moveaxis(out, 0, -1)

    for i, level in enumerate(schedule(sigma, iterations)):
        x = _x_step(z, hy, h2, lam * sigma**2 / level**2)
        z = self_ensemble(denoise, x, min(float(level), SIGMA_TRAINED), ensemble)
        if MEAN_WINDOW_PX > 0:  # 0: not put back (a benchmark's comparison)
            z += gaussian_filter(x - z, (0, MEAN_WINDOW_PX, MEAN_WINDOW_PX), mode="reflect")
        if callback is not None:
            callback(i, crop(z))
    return crop(z)


def _network_scale(y: np.ndarray, sigma: float | None):
    """Planes (C, H, W) divided by s, s and sigma / s (at least :data:`SIGMA_MIN`).

    s is the peak |y|, into the network's [0, 1] and not past it, or 5 sigma where the noise
    would then be past the network's training (:data:`SIGMA_TRAINED`).
    """
    sigma = estimate_noise_sigma(y) if sigma is None else sigma
    scale = max(float(np.abs(y).max()), sigma / SIGMA_TRAINED)
    planes = y[None] / scale if y.ndim == 2 else np.moveaxis(y, -1, 0) / scale
    return planes, scale, max(sigma / scale, SIGMA_MIN)


def _x_step(z: np.ndarray, hy: np.ndarray, h2: np.ndarray, rho: float) -> np.ndarray:
    """argmin_x ||k * x - y||^2 + rho ||x - z||^2, exact in the Fourier domain."""
    spectrum = (hy + rho * sfft.rfft2(z, workers=WORKERS)) / (h2 + rho)
    return sfft.irfft2(spectrum, s=z.shape[1:], workers=WORKERS)


def _data_term(planes: np.ndarray, k: np.ndarray):
    """The tapered, padded planes (C, H', W'), the crop back, |H|^2 and H* Y of the x-step."""
    padded = [taper_pad(p, pad_width(k.shape)) for p in planes]
    z, keep = np.stack([p for p, _ in padded]), padded[0][1]
    kernels = [k if k.ndim == 2 else k[..., c] for c in range(len(z))]
    otf = np.stack([psf_to_otf(kc, z.shape[1:]) for kc in kernels])
    return z, keep, (otf * otf.conj()).real, otf.conj() * sfft.rfft2(z, workers=WORKERS)


def _checked(image, psf, noise_sigma, iterations, lam, ensemble):
    """The validated image, PSF and sigma (None: to be estimated)."""
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)):
        raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
    if iterations < 1:
        raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
    if not np.isfinite(lam) or lam <= 0:
        raise ParameterError(f"lam must be a finite number > 0, got {lam!r}")
    if isinstance(ensemble, bool) or ensemble not in ENSEMBLES:
        raise ParameterError(f"ensemble must be one of {ENSEMBLES}, got {ensemble!r}")
    y = check_image(image)
    k = check_psf(psf, y.shape)
    sigma = None if noise_sigma is None else check_sigma(noise_sigma)
    return y, k, sigma
