"""pacam_render: a ray-traced simulator of a programmable-aperture camera that codes
motion-invariant blur (Sonoda, Nagahara, Taniguchi, IPSJ Trans. CVA 6, 2014).

Units everywhere: scene mm, time ms, image px. Image coordinates are upright (as displayed).

The subpackages follow the data: ``model`` (the paper's camera, Eqs. 3-18, and the table of
capture modes) -> ``psf`` (analytic PSFs, Eqs. 1, 13, 14) -> ``render`` (Mitsuba variant, the
aperture plan and the ``programmable_aperture`` sensor) -> ``scenes`` -> ``exposure`` (captures
integrated over moving geometry, rendered PSFs) -> ``sensor`` (photons to DN) -> ``restore``
(deconvolution and metrics) -> ``experiments`` (figures, demo, validation) -> ``cli``.

Importing the package imports neither Mitsuba nor Dr.Jit: the sensor plugin registers on the
first :func:`select_variant`, :func:`sensor_dict` or render.
"""

from importlib.metadata import version

from .errors import ParameterError
from .exposure.capture import Capture, CaptureSpec, render_capture, write_capture
from .exposure.record import CaptureRecord, analytic_psf
from .model.camera import CameraDesign, preset, prototype
from .model.design import solve as solve_design
from .model.modes import MODES, Mode, capture_camera, mode
from .model.report import design_report
from .psf.analytic import (
    PSFTruncationWarning,
    coded_psf,
    design_psf,
    discrete_coded_psf,
    flutter_psf,
    levin_psf,
    pillbox_psf,
    short_exposure_psf,
    static_psf,
)
from .render import select_variant, sensor_dict
from .restore import metrics
from .restore.deconvolve import METHODS as DECONVOLUTION_METHODS
from .restore.deconvolve import deconvolve, wiener
from .scenes import load_scene, psf_scene
from .sensor.apply import add_sensor_layers
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

__all__ = [
    "DECONVOLUTION_METHODS",
    "DEFAULT_LIGHT_LEVEL",
    "MODES",
    "CameraDesign",
    "Capture",
    "CaptureRecord",
    "CaptureSpec",
    "Mode",
    "PSFTruncationWarning",
    "ParameterError",
    "SensorCapture",
    "SensorModel",
    "add_sensor_layers",
    "analytic_psf",
    "aperture_area_mm2",
    "available_presets",
    "capture_camera",
    "coded_psf",
    "deconvolve",
    "design_psf",
    "design_report",
    "discrete_coded_psf",
    "flutter_psf",
    "levin_psf",
    "load_scene",
    "metrics",
    "mode",
    "photons_from_render",
    "photons_per_unit",
    "pillbox_psf",
    "preset",
    "prototype",
    "psf_scene",
    "render_capture",
    "select_variant",
    "sensor_dict",
    "short_exposure_psf",
    "simulate_capture",
    "solve_design",
    "static_psf",
    "wiener",
    "write_capture",
]
