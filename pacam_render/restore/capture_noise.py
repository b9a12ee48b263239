"""The noise a capture's layer is deblurred with, and where it came from.

A sensor capture's ``noisy`` layer has the sensor's own Poisson-Gaussian noise, which the
``hl`` and ``tv`` solvers weigh pixel by pixel (:mod:`.noise`); the other methods take one
sigma: the one given, else the one the capture recorded (its other layers are noiseless), else
the layer's wavelet estimate, which is what the deconvolver would estimate itself.
"""

from __future__ import annotations

import numpy as np

from ..capture.record import CaptureRecord
from ..errors import ParameterError
from ..sensor.apply import units_per_input
from ..sensor.model import SensorModel
from .deconvolve import SIGMA_METHODS
from .noise import NoiseModel, estimate_noise_sigma

NOISE_SIGMA_MAX = 1e3
"""The largest ``noise_sigma``, in multiples of the layer's peak (or of white, 1, if the peak
is lower): beyond it the image is all noise, and its square overflows."""


def check_noise_sigma(sigma: float | None, image) -> None:
    """Refuse a ``noise_sigma`` that is not finite, < 0 or above :data:`NOISE_SIGMA_MAX` x
    max(peak, 1) of ``image``; None passes."""
    if sigma is None:
        return
    peak = max(float(np.nanmax(np.abs(image))) if np.size(image) else 0.0, 1.0)
    hi = NOISE_SIGMA_MAX * peak
    if not 0 <= sigma <= hi:  # also NaN
        raise ParameterError(
            f"noise_sigma must be in [0, {hi:.4g}] (the layer's units: up to "
            f"{NOISE_SIGMA_MAX:g}x its peak or white, {peak:.4g}), got {sigma!r}"
        )


NOT_IMAGES = {
    "depth": "depth in mm",
    "velocity": "image velocity in px/ms",
    "object_id": "object numbers",
    "raw": "the sensor's Bayer mosaic in DN (deblur its demosaicked noisy layer)",
    "mc_sigma": "the render's Monte Carlo sigma",
    "relative_illumination": "the relative-illumination map (deconvolve flat-fields with it)",
}
"""Capture layers that are not images of the scene: deblurring them means nothing."""


def deblur_layer(layers, layer: str | None = None) -> str:
    """The layer to deblur: ``layer`` if given, else ``noisy`` when the capture has one (a
    sensor capture), else ``capture``. A layer that is not an image (:data:`NOT_IMAGES`) is
    refused, naming what it holds and the image layers there are."""
    if layer is None:
        return "noisy" if "noisy" in layers else "capture"
    if layer in NOT_IMAGES:
        images = [k for k in layers if k not in NOT_IMAGES]
        raise ParameterError(
            f"`layer` {layer} holds {NOT_IMAGES[layer]}, not an image of the scene; deblur one "
            f"of {', '.join(images)}"
        )
    return layer


def sparse_options(
    method: str,
    layer: str,
    record: CaptureRecord | None,
    colour: str | None = None,
    noise_sigma: float | None = None,
) -> tuple[dict, str | None]:
    """The keywords of the ``hl``/``tv`` solvers for ``layer``.

    Parameters
    ----------
    method : str
        The deconvolution method; ``colour`` is refused for any but ``hl`` and ``tv``.
    layer : str
        The layer to deblur.
    record : CaptureRecord or None
        The capture's record: a sensor capture's own ``noisy`` layer gets the sensor's
        Poisson-Gaussian noise (``noise``) unless ``noise_sigma`` is given.
    colour : {"joint", "channel"}, optional
    noise_sigma : float, optional

    Returns
    -------
    (dict, str or None)
        The keywords, and a description of the noise model when it is the sensor's.
    """
    if method not in ("hl", "tv"):
        if colour is not None:
            raise ParameterError(f"`colour` needs `method` hl or tv, not {method}")
        return {}, None
    kw = {} if colour is None else {"colour": colour}
    own = record is not None and record.sensor is not None and layer == "noisy"
    if own and noise_sigma is None:
        kw["noise"] = layer_noise(record)
        return kw, "the sensor's Poisson-Gaussian noise"
    return kw, None


def deblur_noise(
    method: str,
    kw: dict,
    how: str | None,
    image,
    layer: str,
    layers,
    record: CaptureRecord | None,
    noise_sigma: float | None = None,
) -> dict:
    """The noise the deconvolver is told, and where it came from.

    Sets ``noise_sigma`` in ``kw`` (from :func:`sparse_options`) for the methods that take
    one: ``noise_sigma`` if given, else the sigma the capture recorded when ``layer`` is the
    one that has it, else the layer's wavelet estimate.

    Returns
    -------
    dict
        ``sigma`` (None when not used) and ``source`` (``noise_sigma`` when given; else the
        record, the estimate, or the sensor's model ``how``).
    """
    if "noise" in kw:  # hl/tv on the sensor's own layer: its Poisson-Gaussian model
        return {"sigma": record.known_noise_sigma, "source": how}
    if method not in SIGMA_METHODS:
        return {"sigma": None, "source": f"not used by {method}"}
    known = record is not None and (layer == "noisy" or "noisy" not in layers)
    if noise_sigma is not None:
        sigma, source = noise_sigma, "noise_sigma"
    elif known and record.known_noise_sigma is not None:
        sigma, source = record.known_noise_sigma, "the capture's JSON (noise_sigma)"
    else:
        sigma = estimate_noise_sigma(np.asarray(image, float))
        source = "estimated from the layer (wavelet MAD)"
    kw["noise_sigma"] = sigma
    return {"sigma": sigma, "source": source}


def layer_noise(rec: CaptureRecord):
    """The temporal noise of a sensor capture's ``noisy`` layer, in the layer's units.

    Poisson-Gaussian (:class:`~pacam_render.restore.noise.NoiseModel`), from the recorded
    sensor model and photons per unit; what a weighted deconvolution assumes. Divide the layer
    by ``rec.light_factor`` and use ``.scaled(1 / rec.light_factor)`` for white = 1 units.
    """

    s = rec.sensor
    if s is None:
        raise ParameterError("the capture went through no sensor model: it has no sensor noise")
    model = SensorModel(**s.model)
    back = units_per_input(rec, s.light_level_photons_per_px_per_ms)
    e_per_unit = model.qe * s.photons_per_unit / back
    return NoiseModel.from_sensor(model, e_per_unit, rec.exposure_ms)
