"""How each PSF mode is rendered: the sensor's schedule and windows, where the kernel's origin
lies, and the analytic model's per-window centroids and kernels (:mod:`.render`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_finite
from ..model import schedule as sch
from ..model.camera import CameraDesign
from ..model.modes import (
    MODES,
    MODES_WITH_PSF,
    held_offsets_px,
    image_acceleration,
    mode_exposure_ms,
    sensor_params,
    t0_offset_px,
)
from ..psf.analytic import kernel_from_trajectory
from ..psf.bitmap import bitmap_kernel
from ..psf.trajectory import Segment

RENDER_MODES = MODES_WITH_PSF


@dataclass(frozen=True)
class ModeSetup:
    """How a :func:`~pacam_render.psf.design_psf` mode is rendered.

    ``sensor``: ``configure`` arguments; ``exposure_ms``: the shutter interval [0, exposure];
    ``edges_ms``: window edges (sensor time); ``open``: whether each window lets light in;
    ``origin_px``: film-column offset of the t = 0 image from the point's pinhole image;
    ``a_i``: the model's image acceleration (px/ms^2); ``discrete``: positions held per window;
    ``held_px``: a designed schedule's held (u, v) per window, px from the t = 0 image (None:
    the parabola's a_i t_k^2 / 2 on row 0).
    """

    mode: str
    sensor: dict
    exposure_ms: float
    edges_ms: np.ndarray
    open: np.ndarray
    origin_px: float
    a_i: float
    discrete: bool
    held_px: np.ndarray | None = None

    def held_u_px(self, tm: np.ndarray) -> np.ndarray:
        """Where each discrete window (mid-times tm, ms) holds the still point, columns px."""
        return 0.5 * self.a_i * tm**2 if self.held_px is None else self.held_px[:, 0]

    @property
    def T_ms(self) -> float:
        return 0.5 * self.exposure_ms


def mode_setup(design: CameraDesign, mode: str = "coded") -> ModeSetup:
    """Sensor configuration and time windows that render ``design_psf(design, mode, ...)``.

    Everything but the windows comes from :mod:`pacam_render.model.modes`: the schedule,
    the exposure, a_i and the t = 0 image offset. The design is rendered as given (a PSF
    request names its camera); captures first apply the mode's refocus and opening.
    """
    if mode not in RENDER_MODES:
        raise ParameterError(f"mode must be one of {', '.join(RENDER_MODES)}, got {mode!r}")
    m = MODES[mode]
    sensor = sensor_params(design, mode)
    exposure = mode_exposure_ms(design, mode)
    n, is_open = design.n_patterns, None
    if m.schedule == "flutter":
        is_open = sch.flutter_code().astype(bool)
        n = len(is_open)
    return ModeSetup(
        mode=mode,
        sensor=sensor,
        exposure_ms=exposure,
        edges_ms=np.linspace(0.0, exposure, n + 1),
        open=np.ones(n, dtype=bool) if is_open is None else is_open,
        origin_px=t0_offset_px(design, mode),
        a_i=image_acceleration(design, mode),
        discrete=mode == "flutter" or (m.schedule == "parabolic" and not m.continuous),
        held_px=held_offsets_px(design) if design.designed and mode == "coded" else None,
    )


def model_window_centroids(setup: ModeSetup, velocity: float) -> np.ndarray:
    """Model's centroid (px from the kernel origin) of each window: the mean of x(t) over it.

    Discrete patterns hold a_i t_k^2/2 during window k; continuous ones follow a_i t^2/2.
    """
    T = setup.T_ms
    e = setup.edges_ms - T
    t0, t1 = e[:-1], e[1:]
    tm = 0.5 * (t0 + t1)
    if setup.mode == "flutter":
        return velocity * tm
    if setup.discrete:
        return velocity * tm + setup.held_u_px(tm)
    return velocity * tm + 0.5 * setup.a_i * (t1**3 - t0**3) / (3.0 * (t1 - t0))


def model_window_kernels(design: CameraDesign, mode: str, velocity: float, shape) -> list:
    """The model's pixel-integrated kernel of each window (each normalised; None if shut),
    registered like ``design_psf(..., origin="t0")``: the same estimator (pixel centroids)
    applied to these gives the model's own value, free of Monte Carlo noise."""

    setup = mode_setup(design, mode)
    s = check_finite("velocity (px/ms)", velocity)
    if design.pattern_masks is not None and mode == "coded":
        return _bitmap_window_kernels(design, s, shape)
    T = setup.T_ms
    e = setup.edges_ms - T
    r = 0.0 if mode == "levin" else design.r_px
    out = []
    for k in range(len(e) - 1):
        if not setup.open[k]:
            out.append(None)
            continue
        t0, t1 = float(e[k]), float(e[k + 1])
        tm = 0.5 * (t0 + t1)
        if setup.discrete and mode != "flutter":
            u, v = (0.5 * setup.a_i * tm * tm, 0.0) if setup.held_px is None else setup.held_px[k]
            seg = Segment(t0, t1, float(u), s, 0.0, y=float(v))
        else:
            seg = Segment(t0, t1, 0.0, s, setup.a_i)
        out.append(kernel_from_trajectory([seg], r, size=shape))
    return out


def _bitmap_window_kernels(design: CameraDesign, s: float, shape) -> list:
    """Each window's exact kernel of a bitmap schedule (its pattern alone, the others dark),
    registered on the pattern shown at t = 0 like ``design_psf(..., origin="t0")``."""

    m = design.pattern_masks
    x0 = -t0_offset_px(design, "coded")
    out = []
    for k, pattern in enumerate(m.array):
        if not np.any(pattern > 0):
            out.append(None)
            continue
        alone = np.zeros_like(m.array)
        alone[k] = pattern
        out.append(bitmap_kernel(alone, m.pitch_mm, design.beta_px_per_mm, design.T_ms, s,
                                 size=shape, x0_px=x0, origin="pinhole", max_lost=1.0))  # fmt: skip
    return out
