"""pacam_render: a ray-traced simulator of a programmable-aperture camera that codes
motion-invariant blur (Sonoda, Nagahara, Taniguchi, IPSJ Trans. CVA 6, 2014).

Units everywhere: scene mm, time ms, image px. Image coordinates are upright (as displayed).
"""

from importlib.metadata import version

from .errors import ParameterError
from .model.camera import CameraDesign, preset, prototype
from .model.design import solve as solve_design
from .model.report import design_report
from .psf.analytic import (
    PSFTruncationWarning,
    coded_psf,
    discrete_coded_psf,
    flutter_psf,
    levin_psf,
    pillbox_psf,
    short_exposure_psf,
    static_psf,
)
from .render.aperture_camera import install as _install_aperture_camera
from .render.aperture_camera import sensor_dict
from .render.backend import select_variant
from .sensor.model import (
    DEFAULT_LIGHT_LEVEL,
    SensorCapture,
    SensorModel,
    aperture_area_mm2,
    available_presets,
    photons_from_render,
    photons_per_unit,
    simulate_capture,
)

__version__ = version("pacam_render")

# Registers the `programmable_aperture` sensor for the active Mitsuba variant, and again after
# every variant switch; it never chooses a variant itself, so importing stays light.
_install_aperture_camera()

__all__ = [
    "DEFAULT_LIGHT_LEVEL",
    "SensorCapture",
    "SensorModel",
    "aperture_area_mm2",
    "available_presets",
    "photons_from_render",
    "photons_per_unit",
    "simulate_capture",
    "CameraDesign",
    "PSFTruncationWarning",
    "ParameterError",
    "coded_psf",
    "design_report",
    "discrete_coded_psf",
    "flutter_psf",
    "levin_psf",
    "pillbox_psf",
    "preset",
    "prototype",
    "select_variant",
    "sensor_dict",
    "short_exposure_psf",
    "solve_design",
    "static_psf",
]
