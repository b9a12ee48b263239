"""The noise a deconvolver assumes: Poisson-Gaussian, var(y) = shot y + floor + (prnu y)^2.

A sensor's temporal noise grows with the signal (photon shot noise) above a floor of read,
dark-current and quantisation noise (EMVA 1288's linear model, :mod:`pacam_render.sensor.model`).
A data term weighted by 1 / var(y) is the Gaussian approximation of that likelihood: bright
pixels, which are noisier in absolute terms, count less. We weight the data term rather than
apply a variance-stabilising transform (the generalised Anscombe transform): the transform makes
the noise white but turns the blur into a non-linear operator, so the FFT x-step of
:mod:`.splitting` would no longer be exact.

A white noise sigma, known or estimated from the image (:func:`estimate_noise_sigma`), is the
special case shot = prnu = 0 (:meth:`NoiseModel.white`).

Units: ``y`` in the image's own units; the sensor's electrons per image unit make the link
(:meth:`NoiseModel.from_sensor`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_finite, check_positive

VARIANCE_FLOOR = 1e-12
"""Smallest variance used in a weight, relative to the image's bright end squared."""
SIGMA_FLOOR = 1e-6
"""Wiener's smallest noise sigma, relative to the image's peak (a noiseless render)."""


def estimate_noise_sigma(image: np.ndarray) -> float:
    """Wavelet (MAD) estimate of white-noise sigma, averaged over channels.

    Parameters
    ----------
    image : ndarray
        (H, W), or (H, W, C) with the channels on the last axis.

    Returns
    -------
    sigma : float
        Standard deviation of the noise, in the image's units: the mean over the channels of
        scikit-image's :func:`~skimage.restoration.estimate_sigma` (median absolute deviation of
        the finest wavelet detail coefficients).
    """
    from skimage.restoration import estimate_sigma

    return float(np.mean(estimate_sigma(image, channel_axis=-1 if image.ndim == 3 else None)))


def check_sigma(sigma: float) -> float:
    """``noise_sigma`` as a float, checked finite and >= 0 (else a :class:`ParameterError`)."""
    s = float(sigma)
    if not np.isfinite(s) or s < 0:
        raise ParameterError(f"noise_sigma must be a finite value >= 0, got {sigma!r}")
    return s


@dataclass(frozen=True)
class NoiseModel:
    """Per-pixel noise variance of an image as a function of its mean signal.

    Attributes
    ----------
    shot : float
        Shot-noise variance per unit of signal (1 / electrons per image unit), >= 0.
    floor : float
        Signal-independent variance (read, dark, quantisation), image units^2, >= 0.
    prnu : float
        Photo-response non-uniformity (std / mean of the pixel gain), >= 0: a fixed pattern,
        but an error against the truth all the same.
    saturation : float or None
        Image value at which the sensor clips (full well or ADC top); None: never.
    """

    shot: float = 0.0
    floor: float = 0.0
    prnu: float = 0.0
    saturation: float | None = None

    def __post_init__(self) -> None:
        for name in ("shot", "floor", "prnu"):
            v = check_finite(name, getattr(self, name))
            if v < 0:
                raise ParameterError(f"NoiseModel.{name} must be >= 0, got {v!r}")
        if self.saturation is not None:
            check_positive("NoiseModel.saturation", self.saturation)
        if self.shot == 0 and self.floor == 0 and self.prnu == 0:
            raise ParameterError("NoiseModel needs some noise: shot, floor or prnu > 0")

    @classmethod
    def white(cls, sigma: float) -> NoiseModel:
        """Signal-independent Gaussian noise of standard deviation ``sigma`` (> 0)."""
        s = check_positive("noise_sigma", sigma)
        return cls(floor=s * s)

    @classmethod
    def from_sensor(
        cls, model, electrons_per_unit: float, exposure_ms: float | None = None
    ) -> NoiseModel:
        """The temporal noise of a :class:`~pacam_render.sensor.model.SensorModel` frame.

        Parameters
        ----------
        model : SensorModel
        electrons_per_unit : float
            Mean photo-electrons for 1.0 of the image (qe x photons per unit), > 0.
        exposure_ms : float, optional
            For the dark current's shot noise.

        Returns
        -------
        NoiseModel
            shot = 1 / e_u, floor = (read^2 + dark + dsnu^2 + 1 / (12 K^2)) / e_u^2 and
            saturation = min(full well, ADC top above the dark level) / e_u, with e_u the
            electrons per unit (EMVA 1288's sigma_y^2 = K^2 (sigma_d^2 + mu_e) + sigma_q^2).
        """
        e_u = check_positive("electrons_per_unit", electrons_per_unit)
        dark = model.dark_electrons(exposure_ms)
        floor_e2 = model.read_noise_e**2 + model.dsnu_e**2 + 1.0 / (12.0 * model.K**2)
        if model.shot_noise:
            floor_e2 += dark
        top_e = min(model.full_well_e, (model.max_dn - model.black_offset_dn) / model.K - dark)
        return cls(
            shot=(1.0 / e_u) if model.shot_noise else 0.0,
            floor=floor_e2 / e_u**2,
            prnu=float(model.prnu),
            saturation=max(top_e, 1.0) / e_u,
        )

    def scaled(self, factor: float) -> NoiseModel:
        """The same noise for the image multiplied by ``factor`` (> 0)."""
        f = float(factor)
        sat = None if self.saturation is None else self.saturation * f
        return NoiseModel(self.shot * f, self.floor * f * f, self.prnu, sat)

    def variance(self, signal: np.ndarray) -> np.ndarray:
        """var(y) at a mean ``signal`` (negative signal counts as 0), image units^2."""
        s = np.maximum(np.asarray(signal, dtype=float), 0.0)
        return self.floor + self.shot * s + (self.prnu * s) ** 2

    def saturated(self, image: np.ndarray) -> np.ndarray:
        """Boolean mask of values at the clipping level (within half an electron)."""
        y = np.asarray(image, dtype=float)
        if self.saturation is None:
            return np.zeros(y.shape, dtype=bool)
        margin = 0.5 * self.shot if self.shot > 0 else 1e-6 * self.saturation
        return y >= self.saturation - margin
