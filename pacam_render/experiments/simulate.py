"""Batched image-domain simulation of captures and their deconvolution (paper Section 3).

The paper blurred 30 Flickr photographs. We use the natural photographs that ship offline with
scikit-image (:data:`IMAGE_NAMES`), converted to grey and centre-cropped to squares.

One simulated capture: the scene (reflect-extended past the frame, so blur is linear and does
not wrap around) is convolved with the capture PSF by real FFTs. Noise is added, the result is
deconvolved with the Wiener filter of :mod:`pacam_render.deconvolve` (tapered padding, 1/f^2
prior, known noise sigma), and PSNR is computed against the sharp scene.

Alignment: a motion-invariant PSF at speed s is the s = 0 PSF shifted by -s^2 / 2 a_i (plus a
tail), so deconvolving with the s = 0 PSF returns a shifted image. Each estimate is moved back
by the horizontal shift that maximises its cross-correlation with the scene (sub-pixel: a
parabola through the peak), applied as a Fourier phase ramp, and PSNR is scored on the columns
[margin, W - margin), the same for every speed. This scores deblurring, not registration.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ..errors import ParameterError, check_positive
from ..restore.deconvolve import wiener_spectrum
from ..restore.fourier import WORKERS, pad_width, psf_to_otf, taper_pad
from ..restore.metrics import best_shift_px, psnr_batch

IMAGE_NAMES = (
    "astronaut",
    "brick",
    "camera",
    "chelsea",
    "coffee",
    "coins",
    "grass",
    "gravel",
    "hubble_deep_field",
    "immunohistochemistry",
    "moon",
    "rocket",
    "stereo_motorcycle",
)
"""scikit-image photographs that load offline (documents, duplicates and masks left out)."""


def load_image(name: str, size: int = 256) -> np.ndarray:
    """A grey float64 [0, 1] square crop of a scikit-image photograph, resized to ``size``."""
    from skimage import color, data, transform

    if name not in IMAGE_NAMES:
        raise ParameterError(f"unknown test image {name!r}; valid: {', '.join(IMAGE_NAMES)}")
    img = getattr(data, name)()
    img = img[0] if isinstance(img, tuple) else img  # stereo_motorcycle: (left, right, disp)
    img = color.rgb2gray(img) if img.ndim == 3 else img / 255.0
    h, w = img.shape
    n = min(h, w)
    y0, x0 = (h - n) // 2, (w - n) // 2
    sq = img[y0 : y0 + n, x0 : x0 + n]
    return transform.resize(sq, (size, size), anti_aliasing=True).astype(np.float64)


def load_images(n: int | None = None, size: int = 256) -> np.ndarray:
    """The first n test images (all by default), stacked (N, size, size)."""
    names = IMAGE_NAMES if n is None else IMAGE_NAMES[:n]
    return np.stack([load_image(name, size) for name in names])


@dataclass
class Scenes:
    """Sharp scenes, mirror-extended once, with their spectra kept for every capture PSF."""

    images: np.ndarray  # (N, H, W)
    pad: int  # >= half of the largest kernel side, px

    def __post_init__(self) -> None:
        n, h, w = self.images.shape
        p = self.pad
        self.shape = (sfft.next_fast_len(h + 2 * p, True), sfft.next_fast_len(w + 2 * p, True))
        ext = np.pad(
            self.images,
            ((0, 0), (p, self.shape[0] - h - p), (p, self.shape[1] - w - p)),
            mode="symmetric",
        )
        self.spectra = sfft.rfft2(ext, workers=WORKERS)
        self.crop = (slice(p, p + h), slice(p, p + w))

    def blurred(self, psf: np.ndarray) -> np.ndarray:
        """Linear convolution of each scene with ``psf``, cropped to the frame: (N, H, W)."""
        if max(psf.shape) > 2 * self.pad + 1:
            raise ParameterError(f"psf {psf.shape} needs pad >= {max(psf.shape) // 2} px")
        H = psf_to_otf(psf, self.shape)
        out = sfft.irfft2(self.spectra * H, s=self.shape, workers=WORKERS)
        return out[:, self.crop[0], self.crop[1]]


def wiener_batch(
    captures: np.ndarray, psf: np.ndarray, sigma: float, truth: np.ndarray | None = None
) -> np.ndarray:
    """Wiener-deconvolve a stack of captures with one PSF (the module's prior NSR).

    With ``truth``, each estimate is moved onto it by :func:`best_shift_px` (a Fourier phase
    ramp: exact and sub-pixel) before returning.
    """
    pad = pad_width(psf.shape)
    padded = [taper_pad(c, pad) for c in captures]
    keep = padded[0][1]
    stack = np.stack([p for p, _ in padded])
    shape = stack.shape[1:]
    H = psf_to_otf(psf, shape)
    Y = sfft.rfft2(stack, workers=WORKERS)
    X = np.stack([wiener_spectrum(y, H, shape, max(sigma, 1e-6), "prior") for y in Y])
    if truth is not None:
        Xt = sfft.rfft2(np.stack([taper_pad(t, pad)[0] for t in truth]), workers=WORKERS)
        shift = best_shift_px(X, Xt, shape[1])
        X *= np.exp(2j * np.pi * sfft.rfftfreq(shape[1])[None, :] * shift[:, None])[:, None, :]
    return sfft.irfft2(X, s=shape, workers=WORKERS)[:, keep[0], keep[1]]


NoiseFn = Callable[[np.ndarray, np.random.Generator], tuple[np.ndarray, float]]
"""Turns a stack of noiseless [0, 1] captures into (noisy captures, noise sigma to assume)."""


def gaussian_noise(sigma: float) -> NoiseFn:
    """The paper's noise: additive Gaussian of std ``sigma`` on the [0, 1] image."""

    def add(clean: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        return clean + rng.normal(0.0, sigma, clean.shape), sigma

    return add


def sensor_noise(model, electrons_per_white: float, exposure_ms: float) -> NoiseFn:
    """A physical capture through :class:`~pacam_render.sensor.model.SensorModel`.

    A [0, 1] image (1.0 = white) becomes ``electrons_per_white / qe`` photons per unit, is
    captured to DN, and is brought back to the same scale. The sigma handed to the deconvolver
    is the model's temporal noise at the image's mean level, on that scale.
    """
    e_white = check_positive("electrons_per_white", electrons_per_white, "e-")

    def add(clean: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, float]:
        photons = np.clip(clean, 0.0, None) * (e_white / model.qe)
        seed = int(rng.integers(2**62))
        dn = model.capture(photons, exposure_ms=exposure_ms, seed=seed)
        out = model.electrons_from_dn(dn, exposure_ms) / e_white
        mean_e = float(clean.mean()) * e_white
        sigma = float(np.mean(model.temporal_noise_e(mean_e, exposure_ms))) / e_white
        return out, sigma

    return add


def simulate(
    scenes: Scenes,
    capture_psf: np.ndarray,
    deconv_psf: np.ndarray,
    noise: NoiseFn,
    seed: int,
    margin_px: int,
) -> np.ndarray:
    """PSNR (dB) per scene of: blur with capture_psf, add noise, Wiener with deconv_psf, align."""
    rng = np.random.default_rng(seed)
    noisy, sigma = noise(scenes.blurred(capture_psf), rng)
    est = wiener_batch(noisy, deconv_psf, sigma, truth=scenes.images)
    return psnr_batch(est, scenes.images, margin_px)


def summarise(values: Sequence[float]) -> tuple[float, float]:
    """Mean and standard error."""
    v = np.asarray(values, dtype=float)
    return float(v.mean()), float(v.std(ddof=1) / np.sqrt(v.size)) if v.size > 1 else 0.0
