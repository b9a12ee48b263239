"""Flat-fielding a capture with a relative illumination before it is deblurred.

A capture rendered with ``relative_illumination`` on is irradiance: the radiance image times
the map m (:mod:`pacam_render.model.illumination`), which it stores as its
``relative_illumination`` layer. A camera pipeline divides by m (flat field) before anything
else; the noise is divided too, so its standard deviation grows by 1 / m towards the corners.
The deconvolver is told so: per pixel for the sensor's Poisson-Gaussian model
(:class:`FlatFieldNoise`), as the window's RMS for the methods that take one sigma
(:func:`flat_field_sigma`). Because m depends on the film position alone, the flat-fielded
capture is exactly the radiance image the analytic PSFs describe.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture.record import CAPTURE_UNIT, layer_unit
from ..model.illumination import flat_field
from .noise import NoiseModel

RI_LAYER = "relative_illumination"
"""The layer a capture stores its relative-illumination map in."""


@dataclass(frozen=True, eq=False)
class FlatFieldNoise(NoiseModel):
    """A :class:`NoiseModel` of an image that was divided by a map ``gain`` (h, w).

    A flat-fielded value y = x / g of a raw value x with var(x) = floor + shot x + (prnu x)^2
    has, at its mean signal s = x / g,

        var(y) = floor / g^2 + shot s / g + (prnu s)^2,

    and it clips at saturation / g. ``gain`` broadcasts against (C, H, W) planes and
    (H, W) images alike.
    """

    gain: np.ndarray | None = None

    @classmethod
    def of(cls, noise: NoiseModel, gain: np.ndarray) -> FlatFieldNoise:
        g = np.maximum(np.asarray(gain, dtype=float).reshape(np.shape(gain)[:2]), 1e-30)
        return cls(noise.shot, noise.floor, noise.prnu, noise.saturation, g)

    def scaled(self, factor: float) -> FlatFieldNoise:
        f = float(factor)
        sat = None if self.saturation is None else self.saturation * f
        return FlatFieldNoise(self.shot * f, self.floor * f * f, self.prnu, sat, self.gain)

    def variance(self, signal: np.ndarray) -> np.ndarray:
        s = np.maximum(np.asarray(signal, dtype=float), 0.0)
        g = self.gain
        return self.floor / (g * g) + self.shot * s / g + (self.prnu * s) ** 2

    def saturated(self, image: np.ndarray) -> np.ndarray:
        y = np.asarray(image, dtype=float)
        if self.saturation is None:
            return np.zeros(y.shape, dtype=bool)
        margin = 0.5 * self.shot if self.shot > 0 else 1e-6 * self.saturation
        return y * self.gain >= self.saturation - margin


def flat_field_sigma(sigma: float, ri_map: np.ndarray) -> float:
    """One noise sigma for a flat-fielded image: ``sigma`` / m, RMS over the window,
    sigma sqrt(mean(m^-2)). Exact for signal-independent noise; for shot noise it slightly
    overstates the corners (sigma grows as sqrt(m) there, not as m)."""
    m = np.asarray(ri_map, dtype=float)
    return float(sigma * np.sqrt(np.mean(1.0 / np.maximum(m, 1e-30) ** 2)))


def flat_field_for_deblur(image, layer: str, layers: dict, kw: dict, noise: dict):
    """The layer to deblur, flat-fielded when the capture has a relative-illumination map
    and the layer is one of its own (capture, noisy, subNN), with the deconvolver's noise
    (``kw``) and its description (``noise``) divided alike.

    Returns
    -------
    image : numpy.ndarray
        ``image`` / m, or ``image`` unchanged.
    noise : dict
        ``noise`` with ``flat_field`` True, ``sigma`` divided and ``source`` saying so, when
        flat-fielded.
    """
    m = layers.get(RI_LAYER)
    unit = layer_unit(layer)
    if m is None or unit is None or not unit.startswith(CAPTURE_UNIT):
        return image, noise
    image = flat_field(image, m)
    if isinstance(kw.get("noise"), NoiseModel):
        kw["noise"] = FlatFieldNoise.of(kw["noise"], m)
    if kw.get("noise_sigma") is not None:
        kw["noise_sigma"] = flat_field_sigma(kw["noise_sigma"], m)
    sigma = noise.get("sigma")
    sigma = None if sigma is None else flat_field_sigma(sigma, m)
    how = "per pixel" if isinstance(kw.get("noise"), NoiseModel) else "RMS over the window"
    source = f"{noise['source']}, flat-fielded ({how})"
    return image, {**noise, "sigma": sigma, "source": source, "flat_field": True}
