"""Mitsuba sensor ``pacam_psf_camera``: ``programmable_aperture`` plus one rigid scene velocity.

Mitsuba 3 moves no geometry with ray time. For one point source on black, where everything that
moves shares one velocity, moving the whole scene by v (t - t_mid) is exact and continuous in a
single render. This sensor does that through the base class's documented hook,
:meth:`~pacam_render.render.aperture_camera.ProgrammableApertureCamera.scene_shift`: camera
rays start at o - v tau, and particle-tracer connections see the scene point at p + v tau, tau
being the ray's (window-mapped) paper time. Used by :mod:`pacam_render.psf_render.render`.

Units: velocity in world mm/ms.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi

from ..errors import ParameterError, check_finite
from .aperture_camera import JIT, ProgrammableApertureCamera

VARIANT = mi.variant()
"""The variant this module was imported for (see :mod:`.registry`)."""


class PSFCamera(ProgrammableApertureCamera):
    """``programmable_aperture`` whose whole scene moves at one velocity (mm/ms, world)."""

    def __init__(self, props):
        super().__init__(props)
        self.set_scene_velocity((0.0, 0.0, 0.0))

    def set_scene_velocity(self, v_mm_per_ms) -> None:
        """Move everything the sensor sees by v (t - t_mid): exact continuous motion of a scene
        in which everything moves together (one point source on black)."""
        v = [check_finite("velocity_mm_per_ms", x) for x in v_mm_per_ms]
        if len(v) != 3:
            raise ParameterError(f"velocity_mm_per_ms must have 3 components, got {v!r}")
        self._scene_velocity = tuple(v)
        self._vel = mi.Vector3f(*v)
        if JIT:
            dr.make_opaque(self._vel)  # a new velocity never recompiles

    @property
    def scene_velocity(self) -> tuple[float, float, float]:
        return self._scene_velocity

    def scene_shift(self, tau):
        return self._vel * tau
