"""The image sensor: mean photons per pixel in, noisy digital numbers (DN) out.

:class:`SensorModel` (:mod:`.model`) is the EMVA 1288 chain (quantum efficiency, PRNU, dark
current, exact Poisson shot noise, full well, read noise, DSNU, gain, black offset and ADC),
with its random draws in :mod:`.noise_sources`, an optional Bayer filter (:mod:`.bayer`) and
built-in presets (:mod:`.presets`, :func:`available_presets`: the paper's additive Gaussian
noise and the prototype's Grasshopper ICX285 camera). :func:`simulate_capture` turns a linear
render into photons (:mod:`.radiometry`: ``light_level`` photons/px/ms from a white surface,
scaled by exposure in ms and open area in mm^2) and sends them through the sensor;
:mod:`.apply` adds the ``raw`` and ``noisy`` layers to a capture and records the noise level
that deconvolution should assume.
"""

from .apply import add_sensor_layers, apply_sensor, sensor_sigma
from .model import SensorCapture, SensorModel, simulate_capture
from .presets import PRESETS, available_presets
from .radiometry import (
    DEFAULT_LIGHT_LEVEL,
    aperture_area_mm2,
    photons_from_render,
    photons_per_unit,
)

__all__ = [
    "DEFAULT_LIGHT_LEVEL",
    "PRESETS",
    "SensorCapture",
    "SensorModel",
    "add_sensor_layers",
    "aperture_area_mm2",
    "apply_sensor",
    "available_presets",
    "photons_from_render",
    "photons_per_unit",
    "sensor_sigma",
    "simulate_capture",
]
