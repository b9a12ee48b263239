"""Sparse-prior deconvolution: hyper-Laplacian (Krishnan & Fergus 2009) and total variation.

Both minimise (the solver is :mod:`.splitting`)

    E(x) = sum_i w_i / 2 ((k * x)_i - y_i)^2 + sum_i phi((d_x x)_i) + phi((d_y x)_i)

with phi(g) = |g|^alpha: alpha = 1 for total variation, alpha < 1 for the heavy-tailed gradients
of natural images. The data weight w_i = lambda / var(y_i) follows the noise (:mod:`.noise`):
white (a known sigma, or the wavelet estimate), or the sensor's signal-dependent
Poisson-Gaussian variance, with lambda = :data:`LAMBDA_SCALE` on the image scaled so that its
99.5th percentile is 1 (the prior is not scale-free). Saturated samples get weight 0: their
value is not the blur of the scene. The pad around the image holds the tapered reflection of
:func:`~.fourier.taper_pad`, as for Wiener.

Colour images share one prior across channels (``colour="joint"``) or not (``"channel"``); the
default is the better one per method (:data:`DEFAULT_COLOUR`).

Not here: a data term on the raw Bayer samples (no demosaic before the deblur). Built and
measured in this solver, it scored 0.4-1.3 dB below the demosaicked capture through the ICX285
at 300 photons/px/ms, and at low noise the colours a pixel did not sample form a null space
that the gradient prior alone does not pin down (5 dB on a noiseless test). It needs a
cross-channel (chroma) prior first.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ParameterError
from .fourier import check_image, check_psf, pad_width, psf_to_otf, taper_pad
from .noise import SIGMA_FLOOR, VARIANCE_FLOOR, NoiseModel, check_sigma, estimate_noise_sigma
from .splitting import Problem, solve

HL_ALPHA = 2.0 / 3.0
"""The hyper-Laplacian's exponent (Krishnan & Fergus 2009 use 1/2 and 2/3)."""
LAMBDA_SCALE = {"hl": 0.3, "tv": 0.2}
"""lambda sigma^2 per method, chosen on benchmarks/bench_sparse.py: the best of 0.1, 0.3, 1
over two photographs at sigma = 0.01 and 0.03 (hl's optimum moves from 0.3 to 1 as the noise
grows, tv's stays between 0.1 and 0.3)."""
SCHEDULE = {"hl": (4096.0, 8), "tv": (1024.0, 12)}
"""The prior's penalty at the last iteration and the iterations, per method (it starts at
:data:`.splitting.BETA_START`). On the 13 grey photographs of benchmarks/bench_classical_gap.py
at sigma 0.01, against Krishnan & Fergus' (256, 6): hl 30.74 dB against 30.54, tv 30.47 against
30.27; on 6 colour ICX285 captures hl 26.78 against 26.76, tv 26.36 against 26.17."""
SURE_FACTORS = 2.0 ** (0.75 * np.arange(-2, 3))
"""The multiples of :data:`LAMBDA_SCALE` that ``lambda_scale="sure"`` scores, 0.35 to 2.8: the
best weight per image on the 13 grey photographs spanned 0.1 to 0.63 for hl. Seven at half the
spacing scored the same (hl 30.99 dB, tv 30.97) at 1.5x the time."""
PROBE_SEED = 0x5EED_2013
"""Seed of the Monte-Carlo probe of :func:`sure_lambda` (fixed: the result is deterministic)."""
SURE_SHRINK = 0.8
"""lambda_scale="sure" takes this times the weight of least estimated risk: the risk it can
estimate is the blurred estimate's, which wants less smoothing than the image's. On the 13 grey
photographs at sigma 0.01 (benchmarks/bench_classical_gap.py) 0.8 scored hl 30.99 dB, tv 30.97
(1: 30.90 and 30.96; 0.6: 30.91 and 30.87; the best weight per image on a grid of 11: 31.03
and 31.00; the fixed :data:`LAMBDA_SCALE`: 30.74 and 30.47). At sigma 0.005 and 0.02, where
it was not tuned, it gained hl 0.32 and 0.45 dB over the fixed weight, tv 0.60 and 0.50."""
COLOURS = ("joint", "channel")
"""How colour channels share the prior."""
DEFAULT_COLOUR = {"hl": "joint", "tv": "channel"}
"""The better of the two per method, on 13 colour photographs through the ICX285 at 300
photons/px/ms (benchmarks/bench_deconvolve.py): joint gains hl 0.4 dB (27.28 against 26.87) and
loses tv 0.1 dB (26.35 against 26.45)."""
SIGNAL_WINDOW_PX = 5
"""The variance is read off the image's local mean over this window, not off the noisy value:
a noisy value would weight its own noise (dark draws would count more, biasing the result)."""


def exponent(method: str, alpha: float | None) -> float:
    """The prior's exponent for ``method`` ("hl" or "tv"), checked: alpha in (0, 1], hl only."""
    if method not in LAMBDA_SCALE:
        raise ParameterError(f"sparse method must be 'hl' or 'tv', got {method!r}")
    a = 1.0 if method == "tv" else (HL_ALPHA if alpha is None else float(alpha))
    if not 0.0 < a <= 1.0 or (method == "tv" and alpha not in (None, 1.0)):
        raise ParameterError(f"alpha must be in (0, 1] (hl only), got {alpha!r}")
    return a


def sparse_deconvolve(
    image,
    psf,
    method: str = "hl",
    noise_sigma: float | None = None,
    alpha: float | None = None,
    *,
    noise: NoiseModel | None = None,
    colour: str | None = None,
    iterations: int | None = None,
    lambda_scale: float | str | None = None,
    callback: Callable[[int, np.ndarray], None] | None = None,
) -> np.ndarray:
    """Hyper-Laplacian (``"hl"``) or total-variation (``"tv"``) deconvolution.

    Parameters
    ----------
    image : array_like
        Blurred, noisy, linear image: (H, W) or (H, W, C).
    psf : array_like
        (h, w) or (h, w, C) PSF, px, as for :func:`~.deconvolve.wiener`.
    method : {"hl", "tv"}
    noise_sigma : float, optional
        White noise's standard deviation, image units; None (and no ``noise``): estimated
        (:func:`~.noise.estimate_noise_sigma`).
    alpha : float, optional
        hl's exponent in (0, 1] (default :data:`HL_ALPHA`).
    noise : NoiseModel, optional
        Signal-dependent noise and saturation (:meth:`.NoiseModel.from_sensor`); not with
        ``noise_sigma``.
    colour : {"joint", "channel"}, optional
        One prior on each gradient's colour vector, or one per channel; default: the better one
        for the method (:data:`DEFAULT_COLOUR`).
    iterations : int, optional
        Solver iterations (steps of the prior's penalty), >= 1; default the method's
        (:data:`SCHEDULE`).
    lambda_scale : float or "sure", optional
        The data weight lambda sigma^2, > 0; default the method's (:data:`LAMBDA_SCALE`).
        ``"sure"`` picks it per image from the noise (:func:`sure_lambda`), at 11 solves' cost,
        for noise independent from pixel to pixel: on demosaicked colour captures, whose noise
        the demosaic correlates, it lost 1.2 dB (benchmarks/bench_classical_gap.py).
    callback : callable, optional
        ``callback(i, estimate)`` after each iteration, with the cropped estimate.

    Returns
    -------
    ndarray of float64
        The estimate, same shape as ``image``.

    Raises
    ------
    ParameterError
        For a bad method, alpha, colour, iteration count, lambda_scale, noise, image or PSF.
    """
    a = exponent(method, alpha)
    colour = DEFAULT_COLOUR[method] if colour is None else colour
    beta_stop, default_iterations = SCHEDULE[method]
    iterations = default_iterations if iterations is None else iterations
    y, k, noise = _checked(image, psf, noise, noise_sigma, colour, iterations)
    lam = _checked_lambda(lambda_scale, method)
    if not y.any():
        return np.zeros_like(y)
    scale = float(np.percentile(np.abs(y), 99.5)) or float(np.abs(y).max())
    planes = y[None] / scale if y.ndim == 2 else np.moveaxis(y, -1, 0) / scale
    if noise is None:  # estimated, in the image's units
        sigma = estimate_noise_sigma(y)
        noise = NoiseModel.white(max(sigma, SIGMA_FLOOR * scale))
    noise = noise.scaled(1.0 / scale)
    run = (a, colour == "joint", iterations, beta_stop)
    if lam is None:
        lam = sure_lambda(planes, noise, k, LAMBDA_SCALE[method], run)
    p, keep, x0 = _padded_problem(planes, data_weight(planes, noise, lam), k, a, run[1])
    crop = _cropper(keep, scale, y.ndim == 2)
    cb = None if callback is None else lambda i, x: callback(i, crop(x))
    return crop(solve(p, x0, iterations, cb, beta_stop))


def _checked_lambda(lambda_scale, method: str) -> float | None:
    """The data weight lambda sigma^2, or None for "sure"."""
    if lambda_scale is None:
        return LAMBDA_SCALE[method]
    if isinstance(lambda_scale, str):
        if lambda_scale != "sure":
            raise ParameterError(f"lambda_scale must be > 0 or 'sure', got {lambda_scale!r}")
        return None
    try:
        lam = float(lambda_scale)
    except (TypeError, ValueError):
        lam = float("nan")
    if isinstance(lambda_scale, bool) or not np.isfinite(lam) or lam <= 0.0:
        raise ParameterError(f"lambda_scale must be > 0 or 'sure', got {lambda_scale!r}")
    return lam


def sure_lambda(planes: np.ndarray, noise: NoiseModel, k: np.ndarray, lam0: float, run) -> float:
    """The data weight lambda sigma^2 of least estimated risk, times :data:`SURE_SHRINK`.

    Parameters
    ----------
    planes : ndarray
        (C, H, W) image, channels first, scaled as the solver sees it.
    noise : NoiseModel
        Its noise, in the same units.
    k : ndarray
        The checked PSF.
    lam0 : float
        The method's lambda sigma^2; the candidates are it times :data:`SURE_FACTORS`.
    run : tuple
        (alpha, joint, iterations, beta_stop) of the solves.

    Returns
    -------
    float
        The chosen lambda sigma^2.

    Notes
    -----
    Stein's unbiased risk estimate of the blurred estimate's error, sum_i (k * x - k * x_true)_i^2
    / var_i over the weighted samples: sum_i r_i^2 / var_i - n + 2 div, with the divergence of
    y -> k * x(y) by one Monte-Carlo probe (Ramani et al. 2008), a fixed standard normal b and a
    step eps of 0.1 noise sigma: b . (k * x(y + eps b) - k * x(y)) / eps. The minimum is refined
    by a parabola through the risks at its neighbours in log lambda. The estimate assumes
    independent noise per sample; a demosaic's correlated noise makes it pick too high a weight.
    """
    # a seed of its own: simulated noise is often drawn with seed 0, and a probe equal to the
    # noise over sigma biases the divergence (by 0.09 of the risk on a 256 x 256 photograph)
    probe = np.random.default_rng(PROBE_SEED).standard_normal(planes.shape)
    lams = lam0 * SURE_FACTORS
    risks = np.array([_predicted_risk(planes, noise, k, lam, probe, run) for lam in lams])
    j = int(np.argmin(risks))
    step = 0.0
    if 0 < j < len(risks) - 1:
        lo, mid, hi = risks[j - 1 : j + 2]
        curve = lo - 2.0 * mid + hi
        step = float(np.clip(0.5 * (lo - hi) / curve, -1.0, 1.0)) if curve > 0 else 0.0
    log_lams = np.log(lams)
    spacing = log_lams[1] - log_lams[0]
    return SURE_SHRINK * float(np.exp(log_lams[j] + step * spacing))


def _predicted_risk(planes, noise, k, lam: float, probe: np.ndarray, run) -> float:
    """SURE of the blurred estimate at one lambda sigma^2, per weighted sample."""
    alpha, joint, iterations, beta_stop = run
    weight = data_weight(planes, noise, lam)
    seen = weight > 0
    if not seen.any():
        return 0.0
    eps = 0.1 * float(np.sqrt(np.mean(lam / weight[seen])))
    blurred = []
    for y in (planes, planes + eps * probe):
        p, keep, x0 = _padded_problem(y, weight, k, alpha, joint)
        x = solve(p, x0, iterations, beta_stop=beta_stop)
        blurred.append(p.ifft(p.otf * p.fft(x))[(slice(None), *keep)])
    r = blurred[0] - planes
    div = float(np.sum((probe * (blurred[1] - blurred[0]))[seen])) / eps
    return (float(np.sum((weight * r * r)[seen])) / lam - seen.sum() + 2.0 * div) / seen.sum()


def _checked(image, psf, noise, noise_sigma, colour, iterations):
    """The validated image, PSF and noise (None: to be estimated), in the image's units."""
    if colour not in COLOURS:
        raise ParameterError(f"colour must be one of {', '.join(COLOURS)}, got {colour!r}")
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)):
        raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
    if iterations < 1:
        raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
    y = check_image(image)
    k = check_psf(psf, y.shape)
    if noise is not None and noise_sigma is not None:
        raise ParameterError("give noise (a NoiseModel) or noise_sigma, not both")
    if noise is not None and not isinstance(noise, NoiseModel):
        raise ParameterError(f"noise must be a NoiseModel, got {type(noise).__name__}")
    if noise_sigma is not None:
        sigma = check_sigma(noise_sigma)
        noise = NoiseModel.white(max(sigma, SIGMA_FLOOR * float(np.abs(y).max() or 1.0)))
    return y, k, noise


def data_weight(planes: np.ndarray, noise: NoiseModel, lam: float) -> np.ndarray:
    """lam / var(y), and 0 where a sample is saturated (and its 3 x 3 neighbours, which a
    demosaic interpolated from it); all (C, H, W).

    The variance is the noise model's at the image's local mean (:data:`SIGNAL_WINDOW_PX`).
    """
    from scipy.ndimage import binary_dilation, uniform_filter

    signal = uniform_filter(planes, size=(1, SIGNAL_WINDOW_PX, SIGNAL_WINDOW_PX), mode="reflect")
    var = np.maximum(noise.variance(signal), VARIANCE_FLOOR)
    bad = noise.saturated(planes)
    if bad.any():
        bad = binary_dilation(bad, structure=np.ones((1, 3, 3), dtype=bool))
    return np.where(bad, 0.0, lam / var)


def _padded_problem(planes, weight, k, alpha: float, joint: bool):
    """The problem on the padded grid: the data and the first guess padded with the tapered
    reflection of :func:`~.fourier.taper_pad`, weighted as the image on average."""
    pad = pad_width(k.shape)
    padded = [taper_pad(g, pad) for g in planes]
    x0, keep = np.stack([xp for xp, _ in padded]), padded[0][1]
    # nobody observed the pad, but at weight 0 the blur's null space there is free and a
    # low-noise deblur diverges (noiseless, sigma 1e-3: 23 dB at weight 0, 47 dB at the mean)
    y = x0.copy()
    seen = weight[weight > 0]
    w = np.full(x0.shape, float(seen.mean()) if seen.size else 0.0)
    y[(slice(None), *keep)] = planes
    w[(slice(None), *keep)] = weight
    kernels = [k if k.ndim == 2 else k[..., c] for c in range(len(x0))]
    otf = np.stack([psf_to_otf(kc, x0.shape[1:]) for kc in kernels])
    return Problem(y, w, otf, alpha, joint), keep, x0


def _cropper(keep, scale: float, grey: bool):
    """Padded (C, Hp, Wp) -> the image's own layout and units."""

    def crop(x: np.ndarray) -> np.ndarray:
        out = scale * x[(slice(None), *keep)]
        return out[0] if grey else np.moveaxis(out, 0, -1)

    return crop
