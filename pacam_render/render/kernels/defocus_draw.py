"""The exact defocused PSF in the rays: where the light from a scene point lands.

Methods of :class:`~.aperture_camera.ProgrammableApertureCamera`, bound into its class body
(as :mod:`.aperture_optics`'), for one variant (re-imported by :mod:`.registry`). With
diffraction on and a disc opening without leakage, ``sample_direction`` puts the light at the
point's chief-ray image through the opening's centre plus an offset drawn from the defocused
disc's exact PSF at the point's own defocus (:mod:`.ray_defocus`): r px, the geometric blur
radius there, gives the edge phase psi = pi r / (2 lambda N). A point defocused beyond
:data:`~.ray_defocus.PSI_MAX` takes the geometric lens point plus the Airy draw, as before
(there the two agree). In RGB a channel is drawn per particle and each channel weighted by its
own density over the mixture's, as the Airy draw does.

The lens point the particle connects through (its visibility) is still drawn uniformly in
the opening: a point partly hidden from the lens is seen through the unhidden part's share
of samples, but its light lands with the whole opening's exact PSF. No ray method is exact
there; the geometric disc is not either.

Path tracing (``sample_ray``) does the same from the film's side once a scene is attached
(:meth:`ExactDefocus.set_probe_scene`, done by :func:`~.passes.render_passes`). The
geometric ray through the film position x and the lens point a (uniform in the opening, as
always) probes the scene for the depth z it meets. There the geometric ray's offset from the
chief ray is g, of length r rho (rho = |a - c| / R: rho^2 is uniform). The exact PSF's
offset is taken in g's direction at the exact radial quantile of the same rho^2, o = Q(rho^2),
and the ray leaves a through the film position x + g - o: over a surface at depth z the film
then integrates the exact PSF, with weight 1, as the particle tracer's. The coupling is the
monotone one, so the jitter g - o is the least there is: in focus (r = 0) it is the Airy
draw, as before; far out of focus only the wave's reshaping of the disc, and every ray still
passes near x's focal-plane point, so that an occluder near the focus hides as geometric
optics does. Where the drawn ray meets another depth than the probe (an occluding edge) it
is an approximation, as every ray method is there. A probe that meets nothing, and a blur
beyond :data:`~.ray_defocus.PSI_MAX`, keep the Airy draw. The probe is one more intersection
per camera ray (:mod:`benchmarks.bench_exact_defocus` measures its cost).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from ..ray_defocus import PSI_MAX, PSI_STEP, QUANTILES, V_STEP, defocus_table
from .types import (
    VARIANT,
    Float,
    Int,
    Point2f,
    Point3f,
    UInt,
    Vector3f,
    as_type,
    gather,
    opaque_array,
    opaque_scalar,
)

__all__ = ["ExactDefocus", "VARIANT"]


class ExactDefocus:
    """The exact-defocus methods of the camera (module docstring). Not a base class."""

    def _set_defocus(self):
        """Upload the tables when diffraction is on (:func:`~.ray_defocus.defocus_table`)."""
        self._defocus = None
        if self._diff is None:
            return
        psis, v, pdf, inv, _ = defocus_table()
        self._defocus = True
        self._df_inv = opaque_array(inv.reshape(-1))
        self._df_pdf = opaque_array(pdf.reshape(-1))
        self._df_rows = opaque_scalar(float(len(psis) - 1))
        self._df_nv = len(v)

    def _exact_defocus_on(self) -> bool:
        """Whether this plan's particles take the exact PSF: a disc opening, no leakage and
        no pixel grid (those keep the geometric lens point and the Airy draw)."""
        return (self._defocus is not None and self._leak is None and self._grid is None
                and "bitmap" not in self._features)  # fmt: skip

    def set_probe_scene(self, scene):
        """Attach the scene that camera rays probe for their depth (path tracing with the
        exact PSF, module docstring); ``None`` detaches it. Without one, camera rays keep the
        geometric lens point and the Airy draw."""
        self._probe = scene

    def _exact_ray_on(self) -> bool:
        """Whether camera rays take the exact PSF: the particles' conditions and a scene."""
        return self._exact_defocus_on() and getattr(self, "_probe", None) is not None

    def _blur_radius_px(self, ref_p, z, cx, cy):
        """The geometric blur radius (px) at depth z of the opening centred (cx, cy)."""
        chief = self._landing(ref_p, Point3f(cx, cy, 0.0), z)
        edge = self._landing(ref_p, Point3f(cx + self._radius, cy, 0.0), z)
        res = self._resolution
        return dr.norm(mi.Vector2f((edge.x - chief.x) * res.x, (edge.y - chief.y) * res.y))

    def _probe_depth(self, time, near_p, aperture_p, origin, active):
        """The camera-frame point the geometric ray (film point ``near_p``, lens point
        ``aperture_p``) meets, and whether it meets one."""
        focus_p = near_p * (self._focus / near_p.z)
        d = dr.normalize(Vector3f(focus_p - aperture_p))
        ray = mi.Ray3f(Point3f(0.0), Vector3f(0.0, 0.0, 1.0))
        ray.time = time
        self._finish(ray, d, origin)
        pi = self._probe.ray_intersect_preliminary(ray, True, active)
        hit = active & pi.is_valid()
        t = dr.select(hit, pi.t, 0.0) + self._near * dr.rcp(d.z)
        return aperture_p + d * t, hit

    def _exact_jitter(self, k, time, film, aperture_p, origin, seeds, active):
        """The film jitter (px) of the exact-PSF ray through ``aperture_p``, each channel's
        weight, and where it applies (module docstring). ``film``: film position (sample
        space)."""
        near_p = self._sample_to_camera @ Point3f(film.x, film.y, 0.0)
        ref_p, hit = self._probe_depth(time, near_p, aperture_p, origin, active)
        z = dr.select(hit, ref_p.z, self._focus)
        cx, cy = self._centre(k, time, active)
        chief = self._landing(ref_p, Point3f(cx, cy, 0.0), z)
        res = self._resolution
        g = mi.Vector2f((film.x - chief.x) * res.x, (film.y - chief.y) * res.y)
        rho2 = dr.squared_norm(mi.Vector2f(aperture_p.x - cx, aperture_p.y - cy)) * (
            1.0 / (self._radius * self._radius)
        )
        r = self._blur_radius_px(ref_p, z, cx, cy)
        length, weight, inside = self._defocus_radius(seeds, r, dr.clip(rho2, 0.0, 1.0), hit)
        g_len = dr.norm(g)
        lens = mi.Vector2f(aperture_p.x - cx, aperture_p.y - cy)
        lens_dir = lens * dr.rcp(dr.maximum(dr.norm(lens), 1e-12))  # its angle is uniform
        # g's direction once it is not rounding error (in focus g is float noise, whose
        # direction is not uniform: an in-focus edge's MTF came out 0.2 high)
        direction = dr.select(g_len > 1e-3, g * dr.rcp(dr.maximum(g_len, 1e-3)), lens_dir)
        return g - direction * length, weight, hit & inside

    def _landing(self, ref_p, lens_p, z):
        """The film position (sample space) where the ray from lens point ``lens_p`` through
        ``ref_p`` (depth z) lands: the lens centre's projection of its focal-plane point."""
        focus_p = lens_p + (ref_p - lens_p) * (self._focus / z)
        screen = self._camera_to_sample @ focus_p
        return Point2f(screen.x, screen.y)

    def _defocus_landing(self, ref_p, z, k, time, seeds, active):
        """The exact landing (sample space), each channel's weight, and where it applies (the
        point's psi within the table)."""
        cx, cy = self._centre(k, time, active)
        chief = self._landing(ref_p, Point3f(cx, cy, 0.0), z)
        r = self._blur_radius_px(ref_p, z, cx, cy)
        off, weight, inside = self._defocus_draw(seeds, r, active)
        res = self._resolution
        return Point2f(chief.x + off.x / res.x, chief.y + off.y / res.y), weight, inside

    def _defocus_draw(self, seeds, r_px, active):
        """An offset (px) from the exact PSF of a disc blurred to r px, each channel's weight,
        and whether psi = pi r / (2 lambda N) is inside the table (per channel: all)."""
        u_phi, u_v = self._hashed(seeds)[1:]
        rho, weight, inside = self._defocus_radius(seeds, r_px, u_v, active)
        s, c_ = dr.sincos(2.0 * math.pi * u_phi)
        return Point2f(rho * c_, rho * s), weight, inside

    def _hashed(self, seeds):
        """Three uniform numbers from the seeds: the Airy draw's (the same TEA hash of the
        same seeds): another mix of the seeds, (s0 ^ 0x27D4EB2F s3, s1 ^ s2), drew measurably
        non-uniform numbers at 4 rounds (an in-focus point's chi^2 1.9 per pixel against the
        Airy pattern's 0.6)."""
        bits = [dr.reinterpret_array(UInt, as_type(Float, x)) for x in seeds]
        h0, h1 = mi.sample_tea_32(bits[0] ^ (bits[2] * UInt(0x9E3779B1)), bits[1] ^ bits[3], 4)
        h2, _ = mi.sample_tea_32(h0, h1, 4)
        unit = 2.0**-32
        return Float(h0) * unit, Float(h1) * unit, Float(h2) * unit

    def _defocus_radius(self, seeds, r_px, u_v, active):
        """The exact PSF's radius (px) at quantile ``u_v`` for a disc blurred to r px, each
        channel's weight (a channel drawn from the seeds), and whether psi is in the table."""
        u_c = self._hashed(seeds)[0]
        ln = self._diff_ln
        if len(ln) == 1:
            ln_c = ln[0]
        else:
            c = dr.clip(Int(dr.floor(u_c * 3.0)), 0, 2)
            ln_c = dr.select(c == 0, ln[0], dr.select(c == 1, ln[1], ln[2]))
        psis = [(0.5 * math.pi) * r_px / x for x in ln]
        inside = psis[0] <= PSI_MAX
        for p in psis[1:]:
            inside &= p <= PSI_MAX
        psi = (0.5 * math.pi) * r_px / ln_c
        v = self._defocus_quantile(psi, u_v, active & inside)
        rho = v * ln_c * (1.0 / math.pi)
        weight = Float(1.0)
        if len(ln) == 3:  # each channel's density in rho over the mixture's
            q = [
                self._defocus_pdf(p, math.pi * rho / x, active & inside) / x
                for p, x in zip(psis, ln)
            ]
            mean = (q[0] + q[1] + q[2]) * (1.0 / 3.0)
            inv = dr.select(mean > 0.0, dr.rcp(mean), 0.0)
            weight = mi.Spectrum(q[0] * inv, q[1] * inv, q[2] * inv)
        return rho, weight, inside

    def _row(self, psi):
        f = dr.clip(psi * (1.0 / PSI_STEP), 0.0, self._df_rows)
        j = UInt(dr.minimum(dr.floor(f), self._df_rows - 1.0))
        return j, f - Float(j)

    def _defocus_quantile(self, psi, u, active):
        """v at quantile u, interpolated between psi's two rows (quantile interpolation)."""
        j, t = self._row(psi)
        x = u * float(QUANTILES)
        i = UInt(dr.minimum(dr.floor(x), QUANTILES - 1))
        fx = x - Float(i)
        out = []
        for row in (j, j + 1):
            base = row * (QUANTILES + 1) + i
            lo = gather(Float, self._df_inv, base, active)
            hi = gather(Float, self._df_inv, base + 1, active)
            out.append(dr.lerp(lo, hi, fx))
        return dr.lerp(out[0], out[1], t)

    def _defocus_pdf(self, psi, v, active):
        """The density of v at psi (bilinear in the table), 0 beyond the grid."""
        j, t = self._row(psi)
        x = v * (1.0 / V_STEP)
        ok = active & (x < float(self._df_nv - 1))
        i = UInt(dr.clip(dr.floor(x), 0.0, float(self._df_nv - 2)))
        fx = x - Float(i)
        out = []
        for row in (j, j + 1):
            base = row * self._df_nv + i
            lo = gather(Float, self._df_pdf, base, ok)
            hi = gather(Float, self._df_pdf, base + 1, ok)
            out.append(dr.lerp(lo, hi, fx))
        return dr.select(ok, dr.lerp(out[0], out[1], t), 0.0)
