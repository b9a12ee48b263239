"""The LCoS's flaws and the opening's diffraction in the ``programmable_aperture`` kernels.

Methods of :class:`~.aperture_camera.ProgrammableApertureCamera`, bound into its class body
(a nanobind type takes one base) (issue 36): the switching time
(``lcos_switching``), the contrast (``lcos_contrast``, a second branch of the aperture sample),
the opening's Airy pattern and the pixel grid's orders (``diffraction_wavelengths``,
``lcos_fill_factor``), each a film-position or pattern draw. Each is absent by default, and
the kernels are then those without it. The physics and the checks are in the camera's module
docstring and :mod:`.ray_diffraction`; this module holds the code, for one variant (re-imported
with :mod:`.types` by :mod:`.registry`).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ...errors import ParameterError, check_finite, check_positive
from ...model.optics import LCOS_PITCH_MM
from ..ray_diffraction import (
    INVERSE_SIZE,
    MAX_ORDER,
    RayDiffractionSpec,
    grid_orders,
    inverse_table,
    order_px,
    radial_table,
)
from .types import (
    VARIANT,
    Float,
    Int,
    Point2f,
    UInt,
    as_type,
    gather,
    opaque_array,
    opaque_scalar,
)

__all__ = ["LCoSOptics", "VARIANT"]


class LCoSOptics:
    """The optics methods of the camera, bound into its class; they read its plan (``_plan``,
    ``_features``) and its kernels' helpers (``_aperture``, ``_centre``, ``_weight_at``,
    ``_edges``). Not a base class: nanobind types take a single base."""

    def _leaky_aperture(self, k, time, sample, active):
        """With a finite LCoS contrast C: an aperture point, its area density and the factor
        on the open opening's ray weight. With probability p (``_leak_p``) a uniform point on
        the whole lens, weighing (1/C) x the full lens's weight / p outside the opening and 0
        inside it (the open branch counts that light); otherwise the opening's point as
        without leakage, weighing 1 / (1 - p). ``sample.x`` is split between the branches,
        so both keep the sampler's strata."""
        p = self._leak_p
        leak = sample.x < p
        u_open = Point2f((sample.x - p) / (1.0 - p), sample.y)
        a, pdf = self._aperture(k, time, dr.select(leak, Point2f(0.5, 0.5), u_open), active)
        u_leak = Point2f(sample.x / dr.maximum(p, 1e-30), sample.y)
        d = mi.warp.square_to_uniform_disk_concentric(u_leak) * self._lens_r
        cx, cy = self._centre(k, time, active)
        inside = dr.square(d.x - cx) + dr.square(d.y - cy) < self._radius * self._radius
        w_leak = dr.select(inside, 0.0, self._leak_w / (p * self._weight_at(k, active)))
        factor = dr.select(leak, w_leak, 1.0 / (1.0 - p))
        a = Point2f(dr.select(leak, d.x, a.x), dr.select(leak, d.y, a.y))
        pdf = dr.select(leak, p * self._inv_lens_area, (1.0 - p) * pdf)
        return a, pdf, factor

    # ---------------------------------------------------------------- LCoS switching
    def _set_switching(self, props):
        """Parse ``lcos_switching`` (ms >= 0; absent or 0: patterns switch at once)."""
        self._switch = None
        t = float(props.get("lcos_switching", 0.0))
        if not (math.isfinite(t) and t >= 0.0):
            raise ParameterError(f"lcos_switching must be a time >= 0 ms, got {t!r}")
        if t == 0.0:
            return
        self._switch = opaque_scalar(t)
        self._switch_ms = t
        self._check_switching(self._plan)

    def _check_switching(self, plan):
        if plan.schedule not in ("parabolic", "centres") or plan.continuous:
            raise ParameterError(
                f"lcos_switching: the {plan.schedule} schedule has no discs switching on the "
                "LCoS (discrete parabolic or centres only)"
            )
        width = plan.duration / plan.n_patterns
        if not self._switch_ms <= width:
            raise ParameterError(
                f"lcos_switching ({self._switch_ms:g} ms) must be at most a pattern's time "
                f"({width:g} ms = the exposure / {plan.n_patterns})"
            )

    def _switched(self, k, time, seeds, active):
        """Pattern k, or k - 1 while the display still turns to k: in the first t of k's
        window, pixels change linearly, so k - 1 is shown with probability 1 - tau / t (tau
        the time into the window; all discs have one area, so the weight is unchanged). The
        display shows pattern 0 before the exposure."""
        tau = time - gather(Float, self._edges, k, active)
        bits = [dr.reinterpret_array(UInt, as_type(Float, x)) for x in seeds]
        u = Float(mi.sample_tea_32(bits[0] ^ bits[1], bits[2] ^ UInt(0x27D4EB2F), 4)[0]) * 2.0**-32
        old = (k > 0) & (tau < self._switch) & (u * self._switch >= tau)
        return dr.select(old, k - 1, k)

    # ---------------------------------------------------------------- LCoS contrast
    def _set_contrast(self, props):
        """Parse ``lcos_contrast`` (C >= 1; absent or inf: an ideal display, the kernels as
        without it)."""
        self._leak = None
        c = props.get("lcos_contrast", math.inf)
        c = check_finite("lcos_contrast", c) if c != math.inf else c
        if not c >= 1.0:
            raise ParameterError(f"lcos_contrast must be >= 1 (1: no coding at all), got {c!r}")
        if c == math.inf:
            return
        self._leak = float(c)
        self._update_contrast(self._plan)

    def _update_contrast(self, plan):
        """The leak branch's probability and weight for the plan's disc (its light share of
        the capture, at least 5 %); only disc schedules on the LCoS leak."""
        if plan.schedule not in ("static", "parabolic", "centres"):
            raise ParameterError(
                f"lcos_contrast: the {plan.schedule} schedule has no leaky LCoS pattern to "
                "model (discs only: static, parabolic, centres)"
            )
        c = self._leak
        open_share = (plan.radius_mm / plan.lens_radius_mm) ** 2
        leak_share = (1.0 - open_share) / c
        p = 0.0 if leak_share <= 0 else max(leak_share / (leak_share + open_share), 0.05)
        self._leak_p = opaque_scalar(min(p, 0.95))
        self._leak_w = opaque_scalar(plan.time_scale / c)
        self._lens_r = opaque_scalar(plan.lens_radius_mm)
        self._inv_lens_area = opaque_scalar(1.0 / (math.pi * plan.lens_radius_mm**2))

    # ---------------------------------------------------------------- diffraction
    def _set_diffraction(self, props):
        """Parse ``diffraction_wavelengths`` (with ``pupil_distance`` and ``pixel_pitch``) and
        upload the Airy pattern's radial table (:mod:`.ray_diffraction`). Absent: no
        diffraction, and the kernels are those without it."""
        self._diff = None
        value = props.get("diffraction_wavelengths", "")
        if value in ("", None):
            if float(props.get("lcos_fill_factor", 1.0)) != 1.0:
                raise ParameterError(
                    "lcos_fill_factor: the grid's orders are diffraction; give "
                    "diffraction_wavelengths (with pupil_distance and pixel_pitch) too"
                )
            return
        for key in ("pupil_distance", "pixel_pitch"):
            if key not in props:
                raise ParameterError(f"diffraction_wavelengths needs {key} (mm)")
        spec = RayDiffractionSpec(value, props.get("pupil_distance"), props.get("pixel_pitch"))
        channels = 1 if mi.is_monochromatic else 3
        if mi.is_spectral or len(spec.wavelengths_nm) != channels:
            raise ParameterError(
                f"diffraction_wavelengths: give one wavelength per colour channel of the "
                f"{mi.variant()} variant ({channels}; spectral variants are not supported), "
                f"got {len(spec.wavelengths_nm)}"
            )
        v_max, pdf, _, _ = radial_table()
        self._diff_dist = mi.ContinuousDistribution(mi.ScalarVector2f(0.0, v_max), pdf)
        self._diff_inv = opaque_array(inverse_table()[0])
        self._diff = spec
        self._set_grid(props)
        self._update_diffraction(self._plan)

    def _set_grid(self, props):
        """``lcos_fill_factor`` f < 1 (with diffraction): the LCoS pixel grid's orders, at
        ``mask_pitch`` (:func:`~.ray_diffraction.grid_orders`); 1 or absent: no grid."""
        self._grid = None
        f = float(props.get("lcos_fill_factor", 1.0))
        probs, _ = grid_orders(f)  # checks f
        if f == 1.0:
            return
        pitch = check_positive("mask_pitch", props.get("mask_pitch", LCOS_PITCH_MM), "mm")
        d = self._diff
        self._grid = f
        self._grid_cdf = [opaque_scalar(float(x)) for x in np.cumsum(probs)[:-1]]
        self._grid_d = [
            opaque_scalar(order_px(w, d.pupil_distance_mm, pitch, d.pixel_pitch_mm))
            for w in d.wavelengths_nm
        ]
        self._grid_t = opaque_scalar(f * f)  # the light the grid passes: its area fill

    def _update_diffraction(self, plan):
        """lambda N (px) per channel for the plan's disc; a bitmap schedule is refused."""
        if "bitmap" in plan.kernel_features:
            raise ParameterError(
                "diffraction_wavelengths: diffraction in the rays needs disc openings; a "
                "bitmap schedule's capture is diffracted after the render, per pattern window"
            )
        self._diff_ln = [opaque_scalar(x) for x in self._diff.lambda_n_px(plan.radius_mm)]

    def _diffraction_text(self) -> str:
        if self._diff is None:
            return "none"
        ln = ", ".join(f"{x:.4g}" for x in self._diff.lambda_n_px(self._plan.radius_mm))
        waves = ", ".join(f"{w:g}" for w in self._diff.wavelengths_nm)
        return f"Airy at {waves} nm (lambda N = {ln} px)"

    def _diffraction_draw(self, seeds, active):
        """An offset (film px) drawn from the Airy pattern and each channel's weight
        (:mod:`.ray_diffraction`). The draws come from a TEA hash of ``seeds`` (four Floats of
        the ray's samples): Mitsuba's RGB and mono integrators pass a wavelength sample of 0,
        and no other dimension is free."""
        bits = [dr.reinterpret_array(UInt, as_type(Float, x)) for x in seeds]
        h0, h1 = mi.sample_tea_32(bits[0] ^ (bits[2] * UInt(0x9E3779B1)), bits[1] ^ bits[3], 4)
        h2, _ = mi.sample_tea_32(h0, h1, 4)
        unit = 2.0**-32
        u_c, u_phi, u_v = Float(h0) * unit, Float(h1) * unit, Float(h2) * unit
        x = u_v * float(INVERSE_SIZE)
        j = UInt(dr.minimum(dr.floor(x), INVERSE_SIZE - 1))
        lo, hi = (
            gather(Float, self._diff_inv, j, active),
            gather(Float, self._diff_inv, j + 1, active),
        )
        v = dr.lerp(lo, hi, x - Float(j))
        ln = self._diff_ln
        if len(ln) == 1:
            ln_c, weight = ln[0], Float(1.0)
        else:
            c = dr.clip(Int(dr.floor(u_c * 3.0)), 0, 2)
            ln_c = dr.select(c == 0, ln[0], dr.select(c == 1, ln[1], ln[2]))
        r = v * ln_c * (1.0 / math.pi)
        if len(ln) == 3:  # each channel's density over the mixture's
            q = [self._diff_dist.eval_pdf_normalized(math.pi * r / x, active) / x for x in ln]
            mean = (q[0] + q[1] + q[2]) * (1.0 / 3.0)
            inv = dr.select(mean > 0.0, dr.rcp(mean), 0.0)
            weight = mi.Spectrum(q[0] * inv, q[1] * inv, q[2] * inv)
        phi = 2.0 * math.pi * u_phi
        s, c_ = dr.sincos(phi)
        off = Point2f(r * c_, r * s)
        if self._grid is not None:
            off, weight = self._grid_draw(h1, h2, off, weight, None if len(ln) == 1 else c)
        return off, weight

    def _grid_draw(self, h1, h2, off, weight, c):
        """The pixel grid's order (m_x, m_y), drawn by its inverse CDF on each axis, added at
        m d_c px (d_c the first order's offset at channel c's wavelength). A ghost (m != 0)
        lands where only channel c's light goes: weight 3 on c (1/3 its chance), 0 on the
        others; the zero order keeps the Airy weights. All times the grid's transmission."""
        h3, h4 = mi.sample_tea_32(h2, h1 ^ UInt(0x85EBCA6B), 4)
        unit = 2.0**-32
        m = []
        for u in (Float(h3) * unit, Float(h4) * unit):
            k = Int(-MAX_ORDER)
            for edge in self._grid_cdf:
                k += dr.select(u >= edge, 1, 0)
            m.append(Float(k))
        d = self._grid_d
        if c is None:
            d_c = d[0]
        else:
            d_c = dr.select(c == 0, d[0], dr.select(c == 1, d[1], d[2]))
        off = Point2f(off.x + m[0] * d_c, off.y + m[1] * d_c)
        if c is not None:
            ghost = (m[0] != 0.0) | (m[1] != 0.0)
            one = [dr.select(c == i, 3.0, 0.0) for i in range(3)]
            weight = dr.select(ghost, mi.Spectrum(one[0], one[1], one[2]), weight)
        return off, weight * self._grid_t
