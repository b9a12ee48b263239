"""A rendered PSF and its windows' trajectory (:class:`RenderedPSF`), and the source size's
effect on a kernel (:func:`source_blur_l1`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import check_positive
from ..psf.analytic import pillbox_psf
from ..restore.metrics import fit_acceleration, kernel_centroid, rel_l1


@dataclass
class RenderedPSF:
    """A rendered PSF (float64, sums to 1, registered like the analytic kernel) and its windows.

    Window arrays (one entry per window): paper times ``t_start_ms``/``t_end_ms`` (t = 0 at
    mid-exposure), ``mass`` (fraction of the PSF), measured centroid ``centroid_u_px``
    (columns, + right) and ``centroid_v_px`` (rows, + down) from the kernel origin, and the
    model's ``model_u_px``. Closed windows (flutter) have mass 0 and NaN centroids.
    """

    kernel: np.ndarray
    raw_sum: float
    mode: str
    velocity_px_per_ms: float
    spp: int
    seed: int
    integrator: str
    seconds: float
    particles: int
    passes: int
    film: dict
    source_radius_px: float
    t_start_ms: np.ndarray
    t_end_ms: np.ndarray
    mass: np.ndarray
    centroid_u_px: np.ndarray
    centroid_v_px: np.ndarray
    model_u_px: np.ndarray
    model_a_i: float
    threads: int | None = 1
    origin: str = "t0"
    window_kernels: list | None = field(default=None, repr=False)
    model: np.ndarray | None = field(default=None, repr=False)
    """The analytic kernel (``design_psf``, same size and registration)."""

    @property
    def t_mid_ms(self) -> np.ndarray:
        return 0.5 * (self.t_start_ms + self.t_end_ms)

    @property
    def fitted_a_i(self) -> float:
        """a_i from a least-squares parabola through the window centroids, px/ms^2."""
        return fit_acceleration(self.t_mid_ms, self.centroid_u_px, self.mass)

    @property
    def centroid_px(self) -> tuple[float, float]:
        return kernel_centroid(self.kernel)

    def to_json(self) -> dict:
        """JSON-ready summary with the per-window centroid trajectory."""

        def num(x):
            x = float(x)
            return x if math.isfinite(x) else None

        traj = [
            {
                "window": k,
                "t_start_ms": num(self.t_start_ms[k]),
                "t_end_ms": num(self.t_end_ms[k]),
                "t_mid_ms": num(self.t_mid_ms[k]),
                "mass": num(self.mass[k]),
                "centroid_u_px": num(self.centroid_u_px[k]),
                "centroid_v_px": num(self.centroid_v_px[k]),
                "model_u_px": num(self.model_u_px[k]),
            }
            for k in range(len(self.mass))
        ]
        cu, cv = self.centroid_px
        return {
            "integrator": f"{self.integrator} (max_depth 2)",
            "rfilter": "box",
            "pixel_format": "luminance, float32 (accumulated in float64 over passes)",
            "spp": self.spp,
            "spp_meaning": "Mitsuba spp per window: particles (ptracer) or camera rays (path) "
            "per film pixel; ptracer traces spp x the full film's pixels even with a crop",
            "seed": self.seed,
            "run_time_s": self.seconds,
            "particles": self.particles,
            "render_calls": self.passes,
            "drjit_threads": self.threads,
            "source_radius_px": self.source_radius_px,
            "film": self.film,
            "raw_sum": self.raw_sum,
            "centroid_px": [cu, cv],
            "fitted_a_i_px_per_ms2": num(self.fitted_a_i),
            "model_a_i_px_per_ms2": self.model_a_i,
            "centroid_trajectory": traj,
            "kernel_origin": self.origin,
            "centroid_convention": "px from the kernel's centre pixel (the t = 0 image for "
            "origin t0, the pinhole image for origin pinhole): u + right, v + down; t in ms, "
            "t = 0 at mid-exposure",
        }


def source_blur_l1(r_px: float, source_radius_px: float, rings: int = 4) -> float:
    """L1 change of a pixel-integrated pillbox of radius r_px when convolved with a uniform
    source disc (quadrature over the source: equal-area rings): the source-size effect."""

    r = check_positive("r_px", r_px, "px")
    rs = float(source_radius_px)
    if rs <= 0:
        return 0.0
    n = 2 * math.ceil(r + rs + 0.5) + 1
    base = pillbox_psf(r, size=n)
    acc = np.zeros_like(base)
    for i in range(rings):
        rr = rs * math.sqrt((i + 0.5) / rings)
        m = 6 * (i + 1)
        for j in range(m):
            th = 2 * math.pi * (j + 0.5 * i) / m
            acc += pillbox_psf(r, size=n, centre=(rr * math.cos(th), rr * math.sin(th))) / (
                rings * m
            )
    return rel_l1(acc, base)
