"""What the deconvolver is told about a capture layer's noise, and the layer it deblurs: one
owner for ``pacam deconvolve``, the study and the rendered-objective optimiser, so that the
three restore one capture alike (issue 46, item 1).

By default the deconvolver is told what a real user of the camera can know: the sensor's
noise from its calibration (Poisson-Gaussian per pixel for ``hl`` and ``tv`` on a sensor's
``noisy`` layer; its RMS for the methods that take one sigma) and, on a rendered capture, the
render's own Monte Carlo sigma, which the real camera does not have but the rendered one does
(added in quadrature). A model error, the capture's departure from the convolution model the
deconvolver assumes, is added only when given: measured on another capture of the same camera
(``model_sigma``, a calibration), or, in a study that asks for it, on the capture being scored
against its own ``sharp`` layer (the oracle: no real camera knows its sharp image).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture.record import CaptureRecord
from .capture_noise import deblur_noise, sparse_options
from .flat_field import flat_field_for_deblur
from .noise import NoiseModel

MODEL_ERRORS = ("none", "oracle")
"""A study's ``model_error``: ``none`` (default: the sensor's and the render's noise only) or
``oracle`` (plus the scored capture's own departure from the model, measured against its
``sharp`` layer); a number is a model sigma calibrated on another capture (white = 1)."""


@dataclass
class DeblurInput:
    """A layer ready to deblur: ``image`` (flat-fielded when the capture has a relative-
    illumination map), the deconvolver's keywords ``kw``, ``noise`` (``sigma``, ``source``)
    and ``how`` (the sensor's noise model in words, or None)."""

    image: np.ndarray
    kw: dict
    noise: dict
    how: str | None


def deblur_input(
    layers: dict,
    layer: str,
    record: CaptureRecord | None,
    method: str,
    colour: str | None = None,
    noise_sigma: float | None = None,
    model_sigma: float | None = None,
) -> DeblurInput:
    """The layer ``layer`` of a capture as the deconvolver gets it (module docstring).

    Parameters
    ----------
    layers : dict
        The capture's layers (its EXR's), in capture units.
    layer : str
        The layer to deblur.
    record : CaptureRecord or None
    method : str
        The deconvolution method.
    colour : {"joint", "channel"}, optional
        For ``hl`` and ``tv``.
    noise_sigma : float, optional
        A sigma to tell the deconvolver instead (capture units): nothing is added to it.
    model_sigma : float, optional
        A model error to add in quadrature, white = 1 (it is scaled by the light factor).

    Returns
    -------
    DeblurInput
    """
    kw, how = sparse_options(method, layer, record, colour, noise_sigma)
    image = layers[layer]
    noise = deblur_noise(method, kw, how, image, layer, layers, record, noise_sigma)
    if noise_sigma is None:
        kw, noise, how = _added_noise(kw, noise, how, layer, record, model_sigma)
    image, noise = flat_field_for_deblur(image, layer, layers, kw, noise)
    if noise.get("flat_field") and how:
        how += ", flat-fielded per pixel"
    return DeblurInput(image, kw, noise, how)


def render_sigma(record: CaptureRecord | None, layer: str) -> float:
    """The render's Monte Carlo sigma in a sensor capture's ``noisy`` layer (capture units; 0
    for another layer, which already states its noise, or without a record of it)."""
    if record is None or record.sensor is None or layer != "noisy":
        return 0.0
    mc = None if record.render_error is None else record.render_error.mc_sigma_white_units
    return 0.0 if mc is None else float(mc) * record.light_factor


def _added_noise(kw, noise, how, layer, record, model_sigma):
    """``kw`` and ``noise`` with the render's Monte Carlo sigma and ``model_sigma`` added in
    quadrature; ``how`` says so."""
    mc = render_sigma(record, layer)
    model = 0.0 if not model_sigma or record is None else float(model_sigma) * record.light_factor
    extra = mc * mc + model * model
    if extra <= 0.0:
        return kw, noise, how
    words = ["the render's Monte Carlo sigma"] if mc else []
    words += [f"a model error {model_sigma:.3g} (white = 1)"] if model else []
    plus = " + " + " + ".join(words)
    noise = {**noise, "render_sigma": mc, "model_sigma": float(model_sigma or 0.0)}
    if isinstance(kw.get("noise"), NoiseModel):
        m = kw["noise"]
        kw["noise"] = NoiseModel(m.shot, m.floor + extra, m.prnu, m.saturation)
        return kw, {**noise, "source": noise["source"] + plus}, (how or "") + plus
    if kw.get("noise_sigma") is not None:
        kw["noise_sigma"] = float(np.sqrt(kw["noise_sigma"] ** 2 + extra))
        noise = {**noise, "sigma": kw["noise_sigma"], "source": noise["source"] + plus}
    return kw, noise, how
