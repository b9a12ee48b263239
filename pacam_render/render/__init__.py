"""The renderer: Mitsuba variant, the aperture plan, the sensor plugins and their masks.

``plan`` (numpy, no Mitsuba) resolves the plugin's parameters; ``sensor`` is the
``programmable_aperture`` Mitsuba sensor and ``psf_camera`` its moving-scene extension, both
imported on first use for the active variant by ``registry``; ``masks`` builds LCoS bitmaps;
``variant`` chooses the Mitsuba variant and ``backend`` activates it. Importing this package
imports neither Mitsuba nor Dr.Jit.
"""

from .backend import select_variant
from .plan import SCHEDULES, AperturePlan, build_plan
from .registry import (
    PLUGIN_NAME,
    PSF_PLUGIN_NAME,
    ensure_registered,
    install,
    register,
    sensor_class,
    sensor_dict,
)
from .variant import BackendWarning

__all__ = [
    "PLUGIN_NAME",
    "PSF_PLUGIN_NAME",
    "SCHEDULES",
    "AperturePlan",
    "BackendWarning",
    "build_plan",
    "ensure_registered",
    "install",
    "register",
    "select_variant",
    "sensor_class",
    "sensor_dict",
]
