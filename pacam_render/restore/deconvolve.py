"""Non-blind deconvolution of coded captures: Wiener (ours), Richardson-Lucy and unsupervised
Wiener (scikit-image), BM3D deblurring (optional ``bm3d`` package), and the dispatcher to every
method (the sparse priors of :mod:`.sparse`, plug-and-play of :mod:`.pnp`).

All methods share the same boundary handling: the image is reflect-padded by the PSF's extent and
the pad is tapered with a raised cosine towards the image mean, so the padded image is periodic
and continuous. That keeps the circular FFT from ringing at the borders. The pad is cropped off
afterwards (:mod:`.fourier`, shared with :mod:`.sparse`).

Wiener noise-to-signal choice (``nsr="prior"``, the default): the image spectrum is modelled as
natural images' S(f) = c / (|f|^2 + f0^2), with f in cycles/px and f0 = 1/N_max; c is fitted
to the observed spectrum where it stands above the noise (see :func:`prior_spectrum`), and the
noise sigma is the known one (capture metadata, or the ``paper`` sensor preset's 0.01) or, if not
given, skimage's wavelet estimate. Then W(f) = H* / (|H|^2 + sigma^2 / S(f)). A scalar ``nsr``
gives the classic constant-balance filter; :func:`oracle_wiener` tunes the prior's scale against
the ground truth, for experiments that need the best case.

Images are float (H, W) or (H, W, C) on any linear scale; PSFs are 2-D (shared) or (h, w, C).
"""

from __future__ import annotations

import importlib.util
import warnings

import numpy as np
import scipy.fft as sfft
from scipy.optimize import minimize_scalar

from ..errors import ParameterError
from .deconvolve_cost import DEFAULT_ITERATIONS, check_deconvolve
from .fourier import WORKERS, check_image, check_psf, pad_width, psf_to_otf, taper_pad
from .metrics import psnr
from .noise import SIGMA_FLOOR, check_sigma, estimate_noise_sigma
from .pnp import INSTALL as PNP_INSTALL
from .pnp import pnp_deconvolve
from .sparse import sparse_deconvolve

METHODS = ("wiener", "hl", "tv", "rl", "uwiener", "bm3d", "pnp")
"""The deconvolution methods ``deconvolve`` takes (``method``)."""
PRIOR_MIN_TRANSFER = 0.2
"""The prior's level is fitted only where the kernel passes at least this share of the power,
|H|^2 >= 0.2 (:func:`prior_spectrum`). Where the s = 0 kernel has a notch, objects at other
depths or speeds (whose blur is not that kernel) still put power, and (|Y|^2/N - sigma^2) / |H|^2
there overstates the level: a 2-D spread of openings has many notches, its fitted c rose 10x and
its restoration lost 4 dB to amplified noise. Measured on four held-out family:occluders windows
(128x64, 300 photons/px/ms, 2 draws), moving / still PSNR as the threshold rises 0, 0.05, 0.1,
0.2, 0.4: prototype 16.83/22.75, 16.90/22.94, 16.97/23.23, 16.98/23.41, 16.97/23.94; random
discs 14.82/21.68 ... 15.40/24.56, 15.41/24.93; Levin 17.27/24.40 ... 17.32/24.67, 17.32/24.68;
normal (a delta kernel) unchanged. The moving objects' gain saturates at 0.2."""
SIGMA_METHODS = ("wiener", "hl", "tv", "bm3d", "pnp")
"""The methods that take a ``noise_sigma`` (rl regularises by its iterations, uwiener
estimates its own)."""
BM3D_LICENCE = (
    "bm3d (Tampere University) is free for non-commercial use only; see the bm3d package licence"
)


# The methods whose package is an optional extra: (the module to import, what to install).
_OPTIONAL = {
    "bm3d": (
        "bm3d",
        "method 'bm3d' needs the optional bm3d package: pip install 'pacam_render[bm3d]' "
        f"({BM3D_LICENCE})",
    ),
    "pnp": ("scico", f"method 'pnp' needs the optional scico package (its DnCNN): {PNP_INSTALL}"),
}


def require_method(method: str) -> None:
    """Raise before any work if ``method``'s optional package is not installed.

    Parameters
    ----------
    method : str
        One of :data:`METHODS` (others pass: :func:`deconvolve` names them).

    Raises
    ------
    ParameterError
        Naming the method and the install command (bm3d, pnp).
    """
    module, message = _OPTIONAL.get(method, (None, ""))
    if module is not None and importlib.util.find_spec(module) is None:
        raise ParameterError(message)


def _per_channel(image: np.ndarray, psf: np.ndarray, fn) -> np.ndarray:
    """Apply fn(channel2d, psf2d) to each channel."""
    if image.ndim == 2:
        return fn(image, psf if psf.ndim == 2 else psf[..., 0])
    chans = [
        fn(image[..., c], psf if psf.ndim == 2 else psf[..., c]) for c in range(image.shape[2])
    ]
    return np.stack(chans, axis=-1)


# --- Wiener -------------------------------------------------------------------------------------
def _freq2(shape: tuple[int, int]) -> np.ndarray:
    fy = sfft.fftfreq(shape[0])[:, None]
    fx = sfft.rfftfreq(shape[1])[None, :]
    return fx * fx + fy * fy


def prior_spectrum(Y: np.ndarray, H2: np.ndarray, shape, sigma: float) -> np.ndarray:
    """1/f^2 image spectrum S(f) = c g(f) in per-pixel DFT units (E|X(f)|^2 = N S(f)).

    The natural-image prior of the Wiener filter, fitted to the observation where it stands
    above the noise.

    Parameters
    ----------
    Y : ndarray of complex
        ``rfft2`` of the (padded) observed image, shape (H, W // 2 + 1).
    H2 : ndarray of float
        |H|^2, the squared magnitude of the OTF on the same grid (:func:`~.fourier.psf_to_otf`).
    shape : tuple of int
        (H, W) of the real-space grid, px; N = H W.
    sigma : float
        Standard deviation of the white noise, in the image's units.

    Returns
    -------
    S : ndarray of float64
        The prior spectrum c g(f), same shape as ``Y``.

    Notes
    -----
    g(f) = 1 / (|f|^2 + f0^2), with f = (f_y, f_x) in cycles/px and f0 = 1 / max(H, W).
    c is the median, over the frequencies where the observation is well above the noise (|Y|^2 /
    N > t sigma^2) and the kernel passes at least :data:`PRIOR_MIN_TRANSFER` of the power (|H|^2
    >= 0.2), DC excluded, of (|Y|^2 / N - sigma^2) / (|H|^2 g): the prior's level where the data
    can see it through the kernel (at a notch, light the kernel does not describe, other depths'
    and speeds', would inflate it). A median, not a mean, so the brightest low frequencies do
    not dominate. For white noise |Y|^2 / (N sigma^2) of a frequency with no signal is Exp(1),
    so t = max(4, ln M) over the grid's M frequencies lets fewer than one noise-only frequency
    in: with t = 4 alone, a very noisy image's noise-only frequencies (e^-4 = 1.8 % of them,
    most where |H|^2 g is small) outnumbered the signal's, the median came out orders of
    magnitude too high and the filter amplified the noise a hundredfold.
    If fewer than 8 frequencies qualify (the image is all noise),
    c matches the observed variance instead: c = max(mean(p) - sigma^2, 1e-20) / mean(g), with
    p = |Y|^2 / N and both means over every row of the grid but the first (which holds DC).
    """
    n = shape[0] * shape[1]
    g = 1.0 / (_freq2(shape) + (1.0 / max(shape)) ** 2)
    p = np.abs(Y) ** 2 / n
    t = max(4.0, float(np.log(p.size)))
    seen = (p > t * sigma**2) & (H2 * g > 0) & (H2 >= PRIOR_MIN_TRANSFER)
    seen[0, 0] = False
    if seen.sum() < 8:  # the image is all noise: fall back to matching its variance
        c = max(float(p[1:].mean()) - sigma**2, 1e-20) / float(g[1:].mean())
    else:
        c = float(np.median((p[seen] - sigma**2) / (H2[seen] * g[seen])))
    return c * g


def wiener_spectrum(Y, H, shape, sigma: float, nsr="prior", scale: float = 1.0) -> np.ndarray:
    """Wiener estimate in the Fourier domain: H* Y / (|H|^2 + NSR(f)), rfft layout.

    Parameters
    ----------
    Y : ndarray of complex
        ``rfft2`` of the (padded) observed image, shape (H, W // 2 + 1).
    H : ndarray of complex
        The OTF on the same grid (:func:`~.fourier.psf_to_otf`).
    shape : tuple of int
        (H, W) of the real-space grid, px.
    sigma : float
        Standard deviation of the white noise, in the image's units; used by the prior only.
    nsr : str or float, optional
        A string (``"prior"``, not checked here: see :func:`wiener`) selects the 1/f^2 prior of
        :func:`prior_spectrum`; a number is a constant noise-to-signal ratio.
    scale : float, optional
        Multiplies the regulariser, of either kind.

    Returns
    -------
    X : ndarray of complex
        The estimate's spectrum, same shape as ``Y``.

    Notes
    -----
    X(f) = H*(f) Y(f) / (|H(f)|^2 + NSR(f)). With the prior, NSR(f) = scale sigma^2 / S(f)
    (S floored at 1e-300) and NSR = 0 at DC: the mean is measured, not guessed. With a constant,
    NSR = scale nsr. The denominator is floored at 1e-300.
    """
    H2 = (H * H.conj()).real
    if isinstance(nsr, str):
        reg = scale * sigma**2 / np.maximum(prior_spectrum(Y, H2, shape, sigma), 1e-300)
        reg[0, 0] = 0.0  # the mean is measured, not guessed: no regularisation at DC
        denom = H2 + reg
    else:
        denom = H2 + scale * float(nsr)
    return H.conj() * Y / np.maximum(denom, 1e-300)


def _wiener2d(y: np.ndarray, k: np.ndarray, sigma: float, nsr, scale: float) -> np.ndarray:
    yp, keep = taper_pad(y, pad_width(k.shape))
    H = psf_to_otf(k, yp.shape)
    Y = sfft.rfft2(yp, workers=WORKERS)
    X = wiener_spectrum(Y, H, yp.shape, sigma, nsr, scale)
    return sfft.irfft2(X, s=yp.shape, workers=WORKERS)[keep]


def wiener(image, psf, noise_sigma: float | None = None, nsr="prior", scale: float = 1.0):
    """Wiener deconvolution. ``nsr``: "prior" (1/f^2 prior, see module doc) or a constant.

    Each channel is reflect-padded by the PSF's extent and tapered
    (:func:`~.fourier.taper_pad`), filtered in the Fourier domain (:func:`wiener_spectrum`) and
    cropped back.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C), float on any linear scale.
    psf : array_like
        PSF, px: (h, w) shared by all channels or (h, w, C), with its origin at the centre pixel
        (h//2, w//2); normalised to unit sum here (:func:`check_psf`).
    noise_sigma : float, optional
        Standard deviation of the white noise, in the image's units: the known one (capture
        metadata, or the ``paper`` sensor preset's 0.01 on a [0, 1] image). None: estimated
        with :func:`~.noise.estimate_noise_sigma`. Used only with ``nsr="prior"``; there 0 (a
        noiseless image) and anything below 1e-6 of the image's peak becomes
        :data:`~.noise.SIGMA_FLOOR` x peak, a vanishing but finite regulariser that keeps H = 0
        bins finite.
    nsr : {"prior"} or float, optional
        ``"prior"`` (default): NSR(f) = sigma^2 / S(f), with S the 1/f^2 natural-image spectrum
        fitted to the observation where it stands above the noise (:func:`prior_spectrum`).
        A finite constant >= 0: the classic constant-balance filter.
    scale : float, optional
        Multiplies the regulariser; 1 uses the prior as fitted (:func:`oracle_wiener` tunes it).

    Returns
    -------
    estimate : ndarray of float64
        The deconvolved image, same shape as ``image``.

    Raises
    ------
    ParameterError
        If ``nsr`` is neither ``"prior"`` nor a finite constant >= 0, if ``noise_sigma`` is
        negative or not finite, or if the image or the PSF is invalid (:func:`check_image`,
        :func:`check_psf`).

    Notes
    -----
    The filter is

        W(f) = H*(f) / (|H(f)|^2 + scale sigma^2 / S(f)),    S(f) = c / (|f|^2 + f0^2),

    with f in cycles/px, f0 = 1 / N_max (the padded grid's longer side), c fitted to the
    observed spectrum where it stands above the noise, and no regularisation at DC. With a
    constant ``nsr``: W(f) = H*(f) / (|H(f)|^2 + scale nsr). One sigma serves every channel.
    """
    y = check_image(image)
    k = check_psf(psf, y.shape)
    if not isinstance(nsr, str):
        if not np.isfinite(nsr) or nsr < 0:
            raise ParameterError(f"nsr must be 'prior' or a constant >= 0, got {nsr!r}")
    elif nsr != "prior":
        raise ParameterError(f"nsr must be 'prior' or a constant >= 0, got {nsr!r}")
    sigma = None if noise_sigma is None else check_sigma(noise_sigma)
    if not y.any():
        return np.zeros_like(y)  # nothing to deblur (and no spectrum to fit a prior to)
    if not isinstance(nsr, str):
        sigma = 0.0  # a constant balance needs no noise level
    else:  # a noiseless (or nearly) input gets a vanishing but finite regulariser
        sigma = estimate_noise_sigma(y) if sigma is None else sigma
        sigma = max(sigma, SIGMA_FLOOR * float(np.abs(y).max()))  # H = 0 bins stay finite
    return _per_channel(y, k, lambda c, kk: _wiener2d(c, kk, sigma, nsr, scale))


def oracle_wiener(image, psf, truth, noise_sigma: float | None = None):
    """Wiener with the prior's scale tuned to maximise PSNR against ``truth`` (best case).

    An oracle, for experiments that need the best case of the prior Wiener filter.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C).
    psf : array_like
        PSF, as for :func:`wiener`.
    truth : array_like
        The sharp image, same shape as ``image``.
    noise_sigma : float, optional
        Noise standard deviation, image units, as for :func:`wiener` (None: estimated).

    Returns
    -------
    estimate : ndarray of float64
        :func:`wiener` with ``nsr="prior"`` at the best scale, same shape as ``image``.
    scale : float
        That scale of the regulariser, in [1e-4, 1e4].

    Raises
    ------
    ParameterError
        If ``truth`` is invalid or its shape differs from the image's, or as :func:`wiener`.

    Notes
    -----
    Maximises PSNR(wiener(image, psf, noise_sigma, "prior", 10^u), truth) (peak 1, so it
    minimises the mean squared error) over u = log10(scale) in [-4, 4], by bounded scalar
    minimisation (:func:`scipy.optimize.minimize_scalar`, ``xatol`` 0.02 decade).
    """
    truth = check_image(truth)
    if truth.shape != np.shape(image):
        raise ParameterError(f"truth shape {truth.shape} != image shape {np.shape(image)}")

    def loss(log_scale: float) -> float:
        est = wiener(image, psf, noise_sigma, "prior", 10.0**log_scale)
        return -psnr(est, truth)

    best = minimize_scalar(loss, bounds=(-4.0, 4.0), method="bounded", options={"xatol": 0.02})
    scale = 10.0 ** float(best.x)
    return wiener(image, psf, noise_sigma, "prior", scale), scale


# --- scikit-image and bm3d ----------------------------------------------------------------------
def _padded(fn):
    """Run a 2-D deconvolver on the tapered, padded image and crop the result."""

    def run(y: np.ndarray, k: np.ndarray) -> np.ndarray:
        yp, keep = taper_pad(y, pad_width(k.shape))
        return fn(yp, k)[keep]

    return run


def richardson_lucy(image, psf, iterations: int = 30, callback=None):
    """Richardson-Lucy deconvolution (scikit-image's iteration).

    Needs a non-negative image; amplifies noise with more iterations, so ``iterations`` is the
    regulariser. Runs on the tapered, padded image (:func:`~.fourier.taper_pad`), cropped back.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C), non-negative.
    psf : array_like
        PSF, as for :func:`wiener`.
    iterations : int, optional
        Number of iterations, an integer >= 1.
    callback : callable, optional
        ``callback(i, estimate)`` after each iteration, with the cropped estimate.

    Returns
    -------
    estimate : ndarray of float64
        The deconvolved image, same shape as ``image``.

    Raises
    ------
    ParameterError
        If ``iterations`` is not an integer >= 1, the image has a negative value, or the image or
        the PSF is invalid.

    Notes
    -----
    Each iteration multiplies the estimate by the back-projected ratio of data to prediction,
    x <- x (k' * (y / (k * x + 1e-12))), with * ``scipy.signal.convolve`` (``mode="same"``)
    and k' the PSF flipped in both axes, from x = 0.5: scikit-image's ``richardson_lucy``
    with ``clip=False`` (nothing clipped), operation for operation, so the estimates are the
    same to the bit; run here, every channel an iteration at a time, so that ``callback`` can
    follow it.
    """
    from scipy.signal import convolve

    y = check_image(image)
    k = check_psf(psf, y.shape)
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
    if y.min() < 0:
        raise ParameterError(f"richardson_lucy needs a non-negative image, min is {y.min():g}")
    if not y.any():
        return np.zeros_like(y)  # RL divides by the prediction: 0 / 0
    planes = [y] if y.ndim == 2 else [y[..., c] for c in range(y.shape[2])]
    padded = [taper_pad(c, pad_width(k.shape)) for c in planes]
    keep = padded[0][1]
    data = [p for p, _ in padded]
    kernels = [k if k.ndim == 2 else k[..., c] for c in range(len(data))]
    est = [np.full(d.shape, 0.5) for d in data]

    def crop() -> np.ndarray:
        out = [x[keep] for x in est]
        return out[0] if y.ndim == 2 else np.stack(out, axis=-1)

    for i in range(int(iterations)):
        for x, d, kk in zip(est, data, kernels):
            conv = convolve(x, kk, mode="same") + 1e-12
            x *= convolve(d / conv, np.flip(kk), mode="same")
        if callback is not None:
            callback(i, crop())
    return crop()


def unsupervised_wiener(image, psf, seed: int = 0):
    """Unsupervised Wiener-Hunt (scikit-image): regularisation estimated by Gibbs sampling.

    Runs on the tapered, padded image (:func:`~.fourier.taper_pad`), cropped back.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C).
    psf : array_like
        PSF, as for :func:`wiener`.
    seed : int, optional
        Seed of the :func:`numpy.random.default_rng` generator that drives the sampler (one
        generator, used by the channels in turn): the same seed gives the same estimate.

    Returns
    -------
    estimate : ndarray of float64
        The posterior mean image, same shape as ``image``.

    Raises
    ------
    ParameterError
        If the image or the PSF is invalid.

    Notes
    -----
    scikit-image's :func:`~skimage.restoration.unsupervised_wiener` (Orieux, Giovannelli and
    Rodet 2010, with its default Laplacian regulariser) samples the image together with the
    noise and image precisions, so no noise level or regularisation weight is given; it is
    called with ``clip=False``.
    """
    from skimage.restoration import unsupervised_wiener as uw

    y = check_image(image)
    k = check_psf(psf, y.shape)
    if not y.any():
        return np.zeros_like(y)
    rng = np.random.default_rng(seed)
    return _per_channel(y, k, _padded(lambda c, kk: uw(c, kk, clip=False, rng=rng)[0]))


def bm3d_deblur(image, psf, noise_sigma: float | None = None):
    """BM3D deblurring (Dabov et al.), as in the paper's real experiments.

    Optional extra: ``pip install bm3d``. Licence: free for non-commercial use only
    (:data:`BM3D_LICENCE`). Runs on the tapered, padded image (:func:`~.fourier.taper_pad`),
    cropped back.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C).
    psf : array_like
        PSF, as for :func:`wiener`.
    noise_sigma : float, optional
        Standard deviation of the white noise, in the image's units; None: estimated with
        :func:`~.noise.estimate_noise_sigma`. Values below 1e-4 are used as 1e-4.

    Returns
    -------
    estimate : ndarray of float64
        The deconvolved image, same shape as ``image``.

    Raises
    ------
    ParameterError
        If the ``bm3d`` package is not installed, ``noise_sigma`` is negative or not finite, or
        the image or the PSF is invalid.

    Notes
    -----
    Calls ``bm3d.bm3d_deblurring`` once per channel, with its warnings silenced. On a numpy
    without ``np.trapz`` (removed in numpy 2.4), it first sets ``np.trapz = np.trapezoid`` for
    the whole process, because bm4d still calls it.
    """
    try:
        import bm3d as _bm3d
    except ImportError as exc:
        raise ParameterError(_OPTIONAL["bm3d"][1]) from exc
    if not hasattr(np, "trapz"):  # bm4d calls np.trapz, which numpy 2.4 removed
        np.trapz = np.trapezoid  # noqa: NPY201 (restoring the name bm4d needs)
    y = check_image(image)
    k = check_psf(psf, y.shape)
    if noise_sigma is not None:
        check_sigma(noise_sigma)
    if not y.any():
        return np.zeros_like(y)  # bm3d refuses a zero noise level on a zero image
    sigma = estimate_noise_sigma(y) if noise_sigma is None else float(noise_sigma)

    def one(c: np.ndarray, kk: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = _bm3d.bm3d_deblurring(c[..., None], max(sigma, 1e-4), kk)  # 2-D needs H x W x 1
        return np.asarray(out).reshape(c.shape)

    return _per_channel(y, k, _padded(one))


def nonnegative_for(method: str, image: np.ndarray) -> tuple[np.ndarray, int]:
    """``image`` clipped at 0 for ``rl``, which needs non-negative data (read noise makes a
    dark pixel of a noisy layer slightly negative), and how many values were clipped; every
    other method gets it as it is."""
    if method != "rl":
        return image, 0
    neg = int(np.count_nonzero(np.asarray(image) < 0))
    return (np.maximum(image, 0.0), neg) if neg else (image, 0)


def deconvolve(image, psf, method: str = "hl", **kwargs):
    """Dispatch to one of :data:`METHODS`.

    Parameters
    ----------
    image : array_like
        Blurred, noisy image, (H, W) or (H, W, C).
    psf : array_like
        PSF, px: (h, w) or (h, w, C), origin at the centre pixel (h//2, w//2).
    method : {"hl", "wiener", "tv", "rl", "uwiener", "bm3d", "pnp"}, optional
        ``hl`` (hyper-Laplacian prior, the default, as ``pacam deconvolve``'s) or ``tv`` (total
        variation), :func:`~.sparse.sparse_deconvolve`; :func:`wiener`;
        :func:`richardson_lucy`, :func:`unsupervised_wiener`, :func:`bm3d_deblur` or
        :func:`~.pnp.pnp_deconvolve` (plug-and-play with a CNN denoiser).
    **kwargs
        Passed on to the method: e.g. ``noise_sigma`` (wiener, hl, tv, bm3d, pnp), ``nsr`` and
        ``scale`` (wiener), ``alpha`` (hl), ``iterations`` (rl, hl, tv, pnp),
        ``lambda_scale`` (hl, tv; ``"sure"`` picks it per image), ``seed`` (uwiener), ``lam``
        (pnp).

    Returns
    -------
    estimate : ndarray of float64
        The deconvolved image, same shape as ``image``.

    Raises
    ------
    ParameterError
        If ``method`` is not one of :data:`METHODS`; before any work, if its memory is not
        available (:func:`~pacam_render.restore.deconvolve_cost.check_deconvolve`, naming the
        methods that fit); or as the method raises it.

    Notes
    -----
    The iterative methods (hl, tv, rl, pnp) show a progress bar over their iterations
    (``tqdm``, after 2 s, on a terminal only).
    """
    funcs = {
        "wiener": wiener,
        "hl": lambda y, k, **kw: sparse_deconvolve(y, k, "hl", **kw),
        "tv": lambda y, k, **kw: sparse_deconvolve(y, k, "tv", **kw),
        "rl": richardson_lucy,
        "uwiener": unsupervised_wiener,
        "bm3d": bm3d_deblur,
        "pnp": pnp_deconvolve,
    }
    if method not in funcs:
        raise ParameterError(f"unknown method {method!r}; valid: {', '.join(METHODS)}")
    shape, kshape = np.shape(image), np.shape(psf)
    if len(shape) in (2, 3) and len(kshape) in (2, 3):  # else the method names the shape
        check_deconvolve(shape, kshape, method, kwargs)
    steps = _iterations(method, kwargs)
    if steps is None:
        return funcs[method](image, psf, **kwargs)
    from tqdm import tqdm

    with tqdm(total=steps, desc=method, unit="it", delay=2.0, disable=None, leave=False) as bar:
        return funcs[method](image, psf, **{**kwargs, "callback": _ticking(kwargs, bar)})


def _iterations(method: str, kwargs: dict) -> int | None:
    """The iterations a progress bar counts for ``method`` (None: no bar)."""
    if method not in DEFAULT_ITERATIONS:
        return None
    n = kwargs.get("iterations", DEFAULT_ITERATIONS[method])
    return n if isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0 else None


def _ticking(kwargs: dict, bar):
    """A callback that moves ``bar`` on, then calls the caller's own ``callback``, if any."""
    own = kwargs.get("callback")

    def tick(i: int, estimate: np.ndarray) -> None:
        bar.update(1)
        if own is not None:
            own(i, estimate)

    return tick
