"""Light levels: the photons that a linear render's pixel stands for.

A render is linear and radiance-like: 1.0 is a white diffuse surface. ``light_level`` is the
number of photons per pixel per ms that such a surface delivers with an aperture of area
``reference_area_mm2`` open (the lens's full clear aperture, F2.8 on the prototype). Photons then
scale with the exposure time and with the open aperture area, so a darker or brighter scene is
one number, ``light_level``. (:func:`~.model.simulate_capture` with ``light_level=None`` uses the
paper's convention instead: 1.0 fills the full well.)

The sensor (:mod:`.model`) sees only photons; these functions are the one place where the
render's units, the exposure and the open aperture area become photons.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ParameterError, check_positive, check_range

DEFAULT_LIGHT_LEVEL = 7000.0
"""Photons/px/ms from a white diffuse surface at the full clear aperture (F2.8 on the prototype).

An estimate for a brightly lit table-top scene, chosen so that with the ``grasshopper-icx285``
preset a white surface at F9.85 over 45 ms (the coded capture) collects about 70 % of the full
well: 7000 * 45 * (2.8 / 9.85)**2 * 0.5 ~ 12700 e- of 18000 e-.
"""

LIGHT_LEVEL_RANGE = (1e-6, 1e9)
"""The light levels taken, photons/px/ms: 1e-6 is a photon per pixel in 20 min, 1e9 saturates
every sensor preset 10^4-fold over a microsecond. Outside it the arithmetic overflows or
underflows (1e308, 1e-300) rather than describing a scene."""


def check_light_level(light_level: Any, name: str = "light_level") -> float:
    """``light_level`` as float, or raise naming ``name`` and :data:`LIGHT_LEVEL_RANGE`.

    Parameters
    ----------
    light_level : float
        Photons/px/ms of white through the reference aperture.
    name : str
        The parameter, for the message.

    Returns
    -------
    float

    Raises
    ------
    ParameterError
        If ``light_level`` is not a finite number in :data:`LIGHT_LEVEL_RANGE`.
    """
    return check_range(name, light_level, *LIGHT_LEVEL_RANGE, "photons/px/ms")


def check_image(name: str, image: Any) -> np.ndarray:
    """``image`` as float64, or raise unless it is a real numeric array, finite and >= 0."""
    img = np.asarray(image)
    if img.dtype.kind not in "iuf":
        raise ParameterError(f"{name} must be a real numeric array, got dtype {img.dtype}")
    img = img.astype(np.float64, copy=False)
    if not np.isfinite(img).all():
        raise ParameterError(f"{name} must be finite and >= 0, got NaN or infinity")
    if img.size and img.min() < 0:
        raise ParameterError(
            f"{name} must be >= 0, got {img.min()!r} (render with a non-negative "
            "reconstruction filter such as box or gaussian)"
        )
    return img


def aperture_area_mm2(radius_mm: float) -> float:
    """Area of a circular opening, pi r^2, mm^2.

    Parameters
    ----------
    radius_mm : float
        Radius of the opening, mm, > 0: e.g. the aperture radius R, or R_max for the lens's full
        clear aperture.

    Returns
    -------
    float
        The area, mm^2.

    Raises
    ------
    ParameterError
        If ``radius_mm`` is not a finite number > 0.
    """
    return math.pi * check_positive("radius_mm", radius_mm, "mm") ** 2


def photons_per_unit(
    light_level: float, exposure_ms: float, open_area_mm2: float, reference_area_mm2: float
) -> float:
    """Photons per pixel over the exposure for 1.0 of the linear render.

    ``light_level`` (photons/px/ms) is what a white diffuse surface delivers with
    ``reference_area_mm2`` open; photons scale with ``exposure_ms`` and ``open_area_mm2``.

    Parameters
    ----------
    light_level : float
        Photons/px/ms from a white diffuse surface with ``reference_area_mm2`` open, > 0.
    exposure_ms : float
        Exposure time, ms, > 0.
    open_area_mm2 : float
        Open aperture area during the exposure, mm^2, > 0.
    reference_area_mm2 : float
        Aperture area at which ``light_level`` is given, mm^2, > 0.

    Returns
    -------
    float
        light_level x exposure_ms x open_area_mm2 / reference_area_mm2, photons.

    Raises
    ------
    ParameterError
        If any argument is not a finite number > 0, or ``light_level`` is outside
        :data:`LIGHT_LEVEL_RANGE`.
    """
    level = check_light_level(light_level)
    t = check_positive("exposure_ms", exposure_ms, "ms")
    a = check_positive("open_area_mm2", open_area_mm2, "mm^2")
    a_ref = check_positive("reference_area_mm2", reference_area_mm2, "mm^2")
    return level * t * a / a_ref


def photons_from_render(
    linear_image: np.ndarray,
    light_level: float,
    exposure_ms: float,
    open_area_mm2: float,
    reference_area_mm2: float,
) -> np.ndarray:
    """Mean photons per pixel for a linear render (1.0 = white diffuse surface), float64.

    The render must not already include the open-area factor: pass the area that the image was
    normalised to as ``reference_area_mm2`` if it does (then ``open_area_mm2`` equal to it).

    Parameters
    ----------
    linear_image : array_like
        The linear render, any shape, real, finite and >= 0.
    light_level : float
        Photons/px/ms from a white diffuse surface with ``reference_area_mm2`` open, > 0.
    exposure_ms : float
        Exposure time, ms, > 0.
    open_area_mm2 : float
        Open aperture area, mm^2, > 0.
    reference_area_mm2 : float
        Aperture area at which ``light_level`` is given, mm^2, > 0.

    Returns
    -------
    ndarray of float64
        ``linear_image`` x :func:`photons_per_unit`, photons, same shape.

    Raises
    ------
    ParameterError
        If the image is not a real numeric array, has NaN, infinite or negative values, or a
        scalar argument is not a finite number > 0.
    """
    img = check_image("linear_image", linear_image)
    return img * photons_per_unit(light_level, exposure_ms, open_area_mm2, reference_area_mm2)
