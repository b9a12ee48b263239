"""pacam_render: a ray-traced simulator of a programmable-aperture camera that codes
motion-invariant blur (Sonoda, Nagahara, Taniguchi, IPSJ Trans. CVA 6, 2014).

Units everywhere: scene mm, time ms, image px. Image coordinates are upright (as displayed).

The subpackages follow the data: ``model`` (the paper's camera, Eqs. 3-18, and the table of
capture modes) -> ``psf`` (analytic PSFs, Eqs. 1, 13, 14) -> ``render`` (Mitsuba variant, the
aperture plan and the ``programmable_aperture`` sensor) -> ``scenes`` -> ``exposure`` (captures
integrated over moving geometry, each resolved once into a plan) and ``psf_render`` (rendered
PSFs) -> ``sensor`` (photons to DN) -> ``restore`` (deconvolution and metrics) ->
``experiments`` (figures, demo, validation) -> ``cli``. A capture's record (``capture``) is data
below all of them, so that its readers import no producer.

Importing the package imports neither Mitsuba nor Dr.Jit: the sensor plugin registers on the
first :func:`select_variant`, :func:`sensor_dict` or render. The names below load their modules
on first use (PEP 562), so ``import pacam_render`` is quick and the ``pacam`` command can catch
Ctrl-C from its first moment.
"""

from __future__ import annotations

import importlib
from importlib.metadata import version
from typing import Any

_EXPORTS = {
    ".errors": ["ParameterError"],
    ".limits": ["PacamWarning", "show_notes"],
    ".capture.files": ["CaptureFile", "read_capture"],
    ".capture.kernels": ["analytic_psf"],
    ".capture.record": ["CaptureRecord"],
    ".capture.result": ["Capture"],
    ".exposure.direct": ["render_capture", "write_capture"],
    ".exposure.spec": ["CaptureSpec"],
    ".exposure.estimate": ["AbsoluteTarget"],
    ".model.camera": ["CameraDesign", "preset", "prototype"],
    ".model.design": [("solve_design", "solve")],
    ".model.design_file": ["read_design", "resolve_design", "write_design"],
    ".model.masks": ["MaskStack"],
    ".model.modes": ["MODES", "Mode", "capture_camera", "mode"],
    ".model.report": ["design_report"],
    ".psf.grid": ["PSFTruncationWarning"],
    ".psf.bitmap": ["bitmap_kernel"],
    ".psf.analytic": [
        "coded_psf",
        "design_psf",
        "discrete_coded_psf",
        "flutter_psf",
        "levin_psf",
        "pillbox_psf",
        "short_exposure_psf",
        "static_psf",
    ],
    ".render": ["select_variant", "sensor_dict"],
    ".restore": ["metrics"],
    ".restore.deconvolve": [("DECONVOLUTION_METHODS", "METHODS"), "deconvolve", "wiener"],
    ".restore.restoration": ["Restoration", "restore_capture"],
    ".scenes": ["load_scene", "psf_scene"],
    ".sensor.apply": ["SensorTarget", "add_sensor_layers"],
    ".sensor.on_capture": ["load_capture", "sensor_on_capture"],
    ".sensor.model": ["SensorCapture", "SensorModel", "simulate_capture"],
    ".sensor.presets": ["available_presets"],
    ".sensor.radiometry": [
        "DEFAULT_LIGHT_LEVEL",
        "aperture_area_mm2",
        "photons_from_render",
        "photons_per_unit",
    ],
}
_WHERE = {
    (e if isinstance(e, str) else e[0]): (mod, e if isinstance(e, str) else e[1])
    for mod, names in _EXPORTS.items()
    for e in names
}

__version__ = version("pacam_render")
__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'pacam_render' has no attribute {name!r}")
    module, attr = _WHERE[name]
    value = getattr(importlib.import_module(module, __name__), attr)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
