"""The schedule look-up of the ``programmable_aperture`` kernels: a ray's time to its pattern,
and that pattern's weight, disc centre and camera offset.

The plan (:class:`~.plan.AperturePlan`) is resolved in float64 on the host; these kernels must
agree with it in float32, boundary for boundary (:func:`lookup`), and must not recompile when
its values change (:meth:`ScheduleLookup._set_schedule` uploads every table opaque). The timing
itself is described in :mod:`.aperture_camera` ("Schedules and time"). Methods of
:class:`~.aperture_camera.ProgrammableApertureCamera`, bound into its class body as
:mod:`.aperture_optics`'s are (a nanobind type takes one base); one variant's code, re-imported
with :mod:`.types` by :mod:`.registry`.
"""

from __future__ import annotations

import drjit as dr
import numpy as np

from ..plan import AperturePlan, f32_up, index_bias
from .types import (
    VARIANT,
    Float,
    Int,
    UInt,
    gather,
    opaque_array,
    opaque_scalar,
)

__all__ = ["ScheduleLookup", "VARIANT", "lookup"]


def lookup(t, edges, n, scale, t0, bias, active):
    """Index k of the window [edges[k], edges[k+1]) containing t (the last one closed).

    (t - t0) * scale is the index up to float32 rounding; lowered by ``bias`` (more than
    that rounding, see :func:`index_bias`) its floor is k or k - 1, and one comparison
    with the next edge (float32, rounded up) settles it, exactly as in float64.
    """
    k = dr.clip(Int(dr.floor((t - t0) * scale - bias)), 0, n - 1)
    hi = gather(Float, edges, UInt(k + 1), active)
    k = dr.select((t >= hi) & (k < n - 1), k + 1, k)
    return UInt(k)


class ScheduleLookup:
    """The schedule methods of the camera, bound into its class; they read its plan's kernel
    features (``_features``). Not a base class: nanobind types take a single base."""

    def _set_schedule(self, plan: AperturePlan):
        """Upload the plan's timing and per-pattern tables (opaque: new values never
        recompile)."""
        dur = plan.duration
        n = plan.n_patterns
        open_idx = np.flatnonzero(plan.is_open).astype(np.uint32)
        self._t_open = opaque_scalar(plan.t_open)
        self._t_mid = opaque_scalar(plan.t_mid)
        self._n = opaque_scalar(n, Int)
        self._scale = opaque_scalar(n / dur if dur > 0 else 0.0)
        self._bias = opaque_scalar(index_bias(plan.t_open, plan.t_close, n))
        self._width = opaque_scalar(dur / n)
        # window edges rounded up to float32: t >= edge exactly when t >= the float64 edge
        self._edges = opaque_array(f32_up(plan.pattern_edges), Float)
        self._n_open = opaque_scalar(len(open_idx), Int)
        self._open_idx = opaque_array(open_idx, UInt)
        self._time_scale = opaque_scalar(plan.time_scale)
        start, length = plan.ray_times
        self._win_open = opaque_scalar(start)
        self._win_len = opaque_scalar(length)
        self._inv_dur = opaque_scalar(1.0 / dur if dur > 0 else 0.0)
        # per-pattern tables, and their first entries for the schedules that need no table
        ratio = plan.area_ratio.astype(np.float32)
        self._weight = opaque_array(ratio)
        self._cx = opaque_array(plan.centres_mm[:, 0].astype(np.float32))
        self._cy = opaque_array(plan.centres_mm[:, 1].astype(np.float32))
        self._cam = opaque_array(plan.camera_x_mm.astype(np.float32))
        open_ratio = ratio[plan.is_open] if plan.is_open.any() else ratio
        self._weight0 = opaque_scalar(float(open_ratio[0]) * plan.time_scale)
        self._cx0 = opaque_scalar(float(plan.centres_mm[0, 0]))
        self._cy0 = opaque_scalar(float(plan.centres_mm[0, 1]))
        self._cam0 = opaque_scalar(float(plan.camera_x_mm[0]))
        self._a_quad = opaque_scalar(plan.aperture_quad)
        self._c_quad = opaque_scalar(plan.camera_quad)

    def _time_and_pattern(self, time, active):
        """The ray's time and pattern from the integrator's time (uniform over the
        exposure). Measure-preserving maps: into the time window, or into the open
        patterns only (closed flutter chops, black masks), the open fraction going into the
        weight. Returns (time, pattern index)."""
        f = self._features
        if "gate" in f:
            u = (time - self._t_open) * self._inv_dur * Float(self._n_open)
            j = dr.clip(Int(dr.floor(u)), 0, self._n_open - 1)
            frac = dr.clip(u - Float(j), 0.0, 1.0)
            k = gather(UInt, self._open_idx, UInt(j), active)
            return self._t_open + (Float(k) + frac) * self._width, k
        if "window" in f:
            u = (time - self._t_open) * self._inv_dur
            time = self._win_open + u * self._win_len
        if "lookup" in f:
            return time, self._pattern(time, active)
        return time, UInt(0)

    def _pattern(self, time, active):
        return lookup(time, self._edges, self._n, self._scale, self._t_open, self._bias, active)

    def _weight_at(self, k, active):
        """Ray weight of pattern k: open-area ratio (0 if shut) x time factor."""
        f = self._features
        # gated flutter samples open chops only, which all have the same area
        if "weights" in f and ("bitmap" in f or "gate" not in f):
            return gather(Float, self._weight, k, active) * self._time_scale
        return self._weight0

    def _camera_x(self, k, time, active):
        f = self._features
        x = gather(Float, self._cam, k, active) if "cam" in f else self._cam0
        if "quad_c" in f:
            tau = time - self._t_mid
            x = x + self._c_quad * tau * tau
        return x

    def _centre(self, k, time, active):
        """Centre (local mm) of pattern k's disc at the ray's time."""
        f = self._features
        cx = gather(Float, self._cx, k, active) if "cx" in f else self._cx0
        cy = gather(Float, self._cy, k, active) if "cy" in f else self._cy0
        if "quad_a" in f:
            tau = time - self._t_mid
            cx = cx + self._a_quad * tau * tau
        return cx, cy
