"""The aperture sampling of the ``programmable_aperture`` kernels: a point of the pattern's
opening, and its area density, from the ray's lens sample.

A disc (every schedule but ``bitmap``) is Mitsuba's concentric map around the pattern's centre,
as ``thinlens`` samples its lens, so the full static opening gives thinlens' rays. A bitmap mask
is sampled in proportion to its transmittance through its run tables
(:class:`~.masks.MaskTables`): a guide table, a short binary search, then a uniform point in
the run. Methods of :class:`~.aperture_camera.ProgrammableApertureCamera`, bound into its class
body as :mod:`.aperture_optics`'s are (a nanobind type takes one base); one variant's code,
re-imported with :mod:`.types` by :mod:`.registry`.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ..plan import AperturePlan
from .types import (
    JIT,
    VARIANT,
    Float,
    Int,
    Point2f,
    UInt,
    gather,
    opaque_array,
    opaque_scalar,
)

__all__ = ["ApertureSampling", "VARIANT"]


class ApertureSampling:
    """The aperture-sampling methods of the camera, bound into its class; they read its plan's
    kernel features (``_features``) and the schedule's disc centre (``_centre``). Not a base
    class: nanobind types take a single base."""

    def _set_openings(self, plan: AperturePlan):
        """Upload the disc's radius and a bitmap schedule's run tables (opaque: new values
        never recompile)."""
        self._radius = opaque_scalar(plan.radius_mm)
        self._inv_disc_area = opaque_scalar(1.0 / (math.pi * plan.radius_mm**2))
        if plan.tables is not None:
            tb = plan.tables
            # one record per run: x_hi, y, span, cdf before it, cdf up to it
            c_hi = tb.cdf.astype(np.float32)
            c_lo = np.concatenate([[0.0], c_hi[:-1]]).astype(np.float32)
            c_lo[tb.start[tb.count > 0]] = 0.0
            rec = np.stack([tb.x_hi_mm, tb.y_mm, tb.span_mm, c_lo, c_hi], axis=1)
            rec = rec.astype(np.float32)
            self._m_rec = rec if not JIT else opaque_array(rec.reshape(-1))
            self._m_start = opaque_array(tb.start, UInt)
            self._m_count = opaque_array(tb.count, UInt)
            self._m_guide = opaque_array(tb.guide, UInt)
            self._m_gstart = opaque_array(tb.guide_start, UInt)
            self._m_pitch = opaque_scalar(tb.pitch_mm)

    def _aperture(self, k, time, sample, active):
        """Aperture point (local mm) for pattern k, and its area density (1/mm^2)."""
        f = self._features
        if "bitmap" in f:
            return self._sample_mask(k, sample, active)
        d = mi.warp.square_to_uniform_disk_concentric(sample) * self._radius
        cx, cy = self._centre(k, time, active)
        return Point2f(d.x + cx, d.y + cy), self._inv_disc_area

    def _rec(self, j, c, active):
        """Field c of run record j: 0 x_hi, 1 y, 2 span, 3 cdf before, 4 cdf up to it."""
        if JIT:  # separate gathers: a Vector gather traces a packet or single gathers
            # depending on Dr.Jit's state, i.e. two kernels (needless recompiles)
            return gather(Float, self._m_rec, j * 5 + c, active)
        return float(self._m_rec[int(j), c]) if active else 0.0

    def _sample_mask(self, k, sample, active):
        """Pick a run of mask k with probability tau x length / sum (CDF inversion: guide
        table, then a binary search over the few runs it leaves), then a uniform point in
        the run. Returns the point (mm) and its area density tau / (sum(tau) pitch^2)."""
        start = gather(UInt, self._m_start, k, active)
        count = gather(UInt, self._m_count, k, active)
        gstart = gather(UInt, self._m_gstart, k, active)
        active = active & (count > 0)
        u = sample.x
        i = UInt(dr.clip(Int(dr.floor(u * Float(count))), 0, Int(count) - 1))
        lo = gather(UInt, self._m_guide, gstart + i, active)
        hi = gather(UInt, self._m_guide, gstart + i + 1, active)

        def cond(lo, hi):
            return lo < hi

        def body(lo, hi):
            mid = (lo + hi) >> 1
            big = self._rec(start + mid, 4, active) > u
            return dr.select(big, lo, mid + 1), dr.select(big, mid, hi)

        lo, hi = dr.while_loop(
            (lo, hi), cond, body, labels=("lo", "hi"), label="aperture mask search"
        )
        j = start + lo
        c_lo, c_hi = self._rec(j, 3, active), self._rec(j, 4, active)
        step = c_hi - c_lo
        r = dr.clip((u - c_lo) / dr.maximum(step, 1e-30), 0.0, 1.0)
        span = self._rec(j, 2, active)
        x = self._rec(j, 0, active) - r * span
        y = self._rec(j, 1, active) + (sample.y - 0.5) * self._m_pitch
        pdf = dr.select(active, step / dr.maximum(span * self._m_pitch, 1e-30), 0.0)
        return Point2f(x, y), pdf
