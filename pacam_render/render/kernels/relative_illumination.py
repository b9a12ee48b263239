"""The relative illumination (natural vignetting) of the ``programmable_aperture`` kernels:
the factor of each ray's film position, on the ray weight of ``sample_ray`` and
``sample_direction`` alike.

The setting is parsed, and a curve tabulated, by :mod:`pacam_render.model.illumination` (numpy);
this module uploads the table and evaluates it, cos^4 or the curve, on the chief ray. The model
is described in :mod:`.aperture_camera` ("Radiometry"). Methods of
:class:`~.aperture_camera.ProgrammableApertureCamera`, bound into its class body as
:mod:`.aperture_optics`'s are (a nanobind type takes one base); one variant's code, re-imported
with :mod:`.types` by :mod:`.registry`.
"""

from __future__ import annotations

import drjit as dr
import numpy as np

from ...errors import check_positive
from ...model.illumination import (
    DEFAULT_RELATIVE_ILLUMINATION,
    TABLE_SIZE,
    film_tan_max,
    parse_relative_illumination,
)
from .types import VARIANT, Float, Int, UInt, gather, opaque_array, opaque_scalar

__all__ = ["RelativeIllumination", "VARIANT"]


class RelativeIllumination:
    """The relative-illumination methods of the camera, bound into its class; they read its
    film and projection (``film()``, ``_x_fov``, ``_focal_px``). Not a base class: nanobind
    types take a single base."""

    def _set_illumination(self, props):
        """Parse ``relative_illumination`` (and ``pixel_pitch`` for a ``height_mm`` curve)
        and upload a curve's table (:mod:`pacam_render.model.illumination`).

        A curve's abscissae become chief-ray tangents with the film's load-time f_px, and the
        curve must reach the film's farthest corner; past its last point it holds its last
        value. The table has a fixed size, so a new curve never recompiles.
        """
        value = props.get("relative_illumination", DEFAULT_RELATIVE_ILLUMINATION)
        pitch = props.get("pixel_pitch", None)
        self._ri = ri = parse_relative_illumination(value)
        self._ri_pitch = None if pitch is None else check_positive("pixel_pitch", pitch, "mm")
        if ri.kind != "curve":
            return
        film = self.film()
        size, crop, off = film.size(), film.crop_size(), film.crop_offset()
        window = (int(off.x), int(off.y), int(crop.x), int(crop.y))
        tan_max = film_tan_max(int(size.x), int(size.y), self._x_fov, window)
        ri.check_covers(tan_max, self._focal_px, self._ri_pitch)
        t_last = float(ri.knots_tan(self._focal_px, self._ri_pitch)[-1])
        self._ri_table = opaque_array(
            ri.table(self._focal_px, self._ri_pitch).astype(np.float32), Float
        )
        self._ri_scale = opaque_scalar((TABLE_SIZE - 1) / t_last)

    def _illumination(self, p):
        """Relative illumination of the film position whose chief ray (through the lens
        centre) passes through the camera-space point ``p`` (p.z > 0).

        ``cos4``: cos^4 theta_c = (z^2 / (x^2 + y^2 + z^2))^2, which stays finite (-> 0)
        towards 90 deg. A curve: linear interpolation in its table, uniform in
        tan theta_c = sqrt(x^2 + y^2) / z.
        """
        r2 = p.x * p.x + p.y * p.y
        z2 = p.z * p.z
        if self._ri.kind == "cos4":
            c2 = z2 / (z2 + r2)
            return c2 * c2
        u = dr.sqrt(r2 / z2) * self._ri_scale
        i = dr.clip(Int(dr.floor(u)), 0, TABLE_SIZE - 2)
        f = dr.clip(u - Float(i), 0.0, 1.0)
        lo = gather(Float, self._ri_table, UInt(i))
        hi = gather(Float, self._ri_table, UInt(i + 1))
        return lo + f * (hi - lo)
