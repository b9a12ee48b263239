"""Where a store's samples land in another camera: the thin lens's refocus shear.

A store is traced through the whole lens (radius R_max) of a thin-lens camera focused at d1.
A sample is a ray: the film point x1 (px of the capture's sensor) and the lens point a (mm, the
plugin's local frame: +x the image's left, +y its top). The same ray, seen by a camera of the
same sensor and field of view focused at d2, lands at

    x2 = x1 - f_px a (1/d2 - 1/d1),      f_px = (W / 2) / tan(fov_x / 2),

for both axes (a thin lens maps the film to its focus plane; Mitsuba's ``thinlens`` and our
plugin keep the field of view when they refocus). For a fixed lens point the map is a
translation, so samples uniform over the film stay uniform: a capture binned from the shifted
samples is unbiased wherever the store's film covers x1 = x2 + f_px a (1/d2 - 1/d1), which the
store's margin guarantees (:func:`margin_px`). ``tests/lightfield`` checks the map ray for ray
against the plugin.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.optics import focal_length_px


def shear_px_per_mm(f_px: float, store_focus_mm: float, focus_mm: float) -> float:
    """k such that x2 = x1 - k a: the film's shift per mm of lens point, px/mm."""
    return f_px * (1.0 / focus_mm - 1.0 / store_focus_mm)


def shifted(x_px: np.ndarray, a_mm: np.ndarray, k_px_per_mm: float) -> np.ndarray:
    """The film coordinate (px, one axis) of samples at ``x_px`` with lens coordinate ``a_mm``
    in a camera whose shear from the store is ``k_px_per_mm``."""
    if k_px_per_mm == 0.0:
        return x_px
    return (x_px - np.float32(k_px_per_mm) * a_mm).astype(np.float32)


def margin_px(k_px_per_mm: float, lens_radius_mm: float) -> int:
    """The store margin (px each side) that a camera of shear ``k_px_per_mm`` needs."""
    return int(math.ceil(abs(k_px_per_mm) * lens_radius_mm - 1e-9))


def enlarged_fov_deg(width_px: int, fov_deg: float, margin: int) -> float:
    """The horizontal field of a sensor ``margin`` px wider on each side, same focal length."""
    return math.degrees(
        2 * math.atan((0.5 * width_px + margin) / focal_length_px(fov_deg, width_px))
    )
