"""The schedule optimiser: the problem a user poses, and a multi-start L-BFGS-B over it.

The reference design is the paper's parabola for the range (:func:`~pacam_render.model.design.
solve`: the preset's F-number, or ``f_number`` / ``r_px``, at the range's middle depth). The
optimiser keeps its opening (equal light) unless the radius is free, and moves the n centres
and the focus. Start 0 is the parabola itself; the others are drawn from ``seed``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from ..errors import ParameterError, check_positive
from ..exposure.render_time import say
from ..limits import duration
from ..model.camera import MIN_FOCUS_MM, MIN_OPENING_LCOS_PX, CameraDesign, preset
from ..model.design import solve
from ..model.design_file import resolve_design
from ..model.schedule_file import check_pattern_count
from ..restore.noise import NoiseModel
from ..sensor.model import SensorModel
from ..sensor.radiometry import check_light_level
from .objective import BETA_RANGE, MEAN_LEVEL, Objective, make_grid

DEFAULT_LIGHT_LEVEL = 300.0
"""Photons/px/ms of white through the full lens: the demo's (``experiments.demo.LIGHT_LEVEL``)."""


@dataclass(frozen=True)
class Problem:
    """What to design for: speeds |s| <= s_max (px/ms), depths, light and sensor."""

    max_velocity_px_per_ms: float
    depth_range_mm: tuple[float, float]
    n_patterns: int
    sensor: str
    light_level: float | None
    preset: str = "prototype"
    f_number: float | None = None
    r_px: float | None = None
    free_radius: bool = False
    design: str | None = None
    """A camera design file to start from instead of ``preset`` (its sensor, lens, LCoS
    pitch and rate, and exposure; the schedule is what is designed)."""


def base_design(p: Problem, depth_mm: float) -> CameraDesign:
    """The camera the schedule is designed for, at ``depth_mm``: the design file's or the
    preset's."""
    if p.design is None:
        return preset(p.preset, object_depth_mm=depth_mm)

    d = resolve_design(p.design, object_depth_mm=depth_mm)
    return d.with_(pattern_centres_mm=None, pattern_masks=None)


def middle_depth_mm(depth_range_mm) -> float:
    """The design depth: the harmonic mean of the range (its middle in 1/Z, where beta is)."""
    near, far = depth_range_mm
    return 2.0 / (1.0 / near + 1.0 / far)


def check_problem(p: Problem) -> None:
    """Every input in range, before any work; messages name the parameter."""
    s = check_positive("max_velocity_px_per_ms", p.max_velocity_px_per_ms, "px/ms")
    near, far = p.depth_range_mm
    for v in (near, far):
        if not (math.isfinite(v) and v >= MIN_FOCUS_MM):
            raise ParameterError(
                f"depth_range_mm must be NEAR,FAR with {MIN_FOCUS_MM:g} <= NEAR <= FAR mm, got "
                f"{near:g},{far:g}"
            )
    if near > far:
        raise ParameterError(
            f"depth_range_mm must be NEAR,FAR with NEAR <= FAR, got {near:g},{far:g}"
        )
    base = base_design(p, middle_depth_mm(p.depth_range_mm))
    check_pattern_count(p.n_patterns, base.exposure_ms, "n_patterns", base.lcos_rate_fps)
    model = SensorModel.from_preset(p.sensor)
    if p.light_level is not None:
        check_light_level(p.light_level)
        if not model.shot_noise:
            raise ParameterError(
                f"light_level: sensor {p.sensor!r} adds noise relative to white whatever the "
                "light (no shot noise); leave light_level out or pick a physical sensor"
            )
    _check_coverable(base, s)


def _check_coverable(base: CameraDesign, s_max: float) -> None:
    """Refuse a range no opening can span: |a_i| T at the smallest opening, strongest focus."""
    z0 = base.object_depth_mm
    beta_max = base.focal_length_px * max(1.0 / z0, 1.0 / MIN_FOCUS_MM - 1.0 / z0)
    r_min = MIN_OPENING_LCOS_PX * base.lcos_pitch_mm
    reach = 4.0 * beta_max * (base.R_max_mm - r_min) / base.T_ms
    if s_max > reach:
        raise ParameterError(
            f"max_velocity_px_per_ms {s_max:g} px/ms: no opening covers it. Even a "
            f"{MIN_OPENING_LCOS_PX:g}-LCoS-px opening with the focus at its limit moves the image "
            f"by |a_i| T = {reach:.3g} px/ms at {z0:g} mm (Eq. 18); lower the speed or lengthen "
            "the exposure"
        )


def reference_design(p: Problem) -> CameraDesign:
    """The paper's parabola covering the range (the design solver), with n patterns."""
    z0 = middle_depth_mm(p.depth_range_mm)
    base = base_design(p, z0).with_(n_patterns=p.n_patterns)
    try:
        return solve(p.max_velocity_px_per_ms, object_depth_mm=z0, f_number=p.f_number,
                     r_px=p.r_px, base=base)  # fmt: skip
    except ParameterError as exc:
        raise ParameterError(f"the parabola cannot cover the range: {exc}") from None


def noise_variance(p: Problem, ref: CameraDesign):
    """sigma^2(R) in white = 1 units at :data:`MEAN_LEVEL`: the sensor's noise at the light an
    opening of radius R collects (without shot noise, relative to white whatever the light)."""
    model = SensorModel.from_preset(p.sensor)
    level = p.light_level if p.light_level is not None else DEFAULT_LIGHT_LEVEL

    def var(R_mm: float) -> float:
        if model.shot_noise:
            e = model.qe * level * ref.exposure_ms * (R_mm / ref.R_max_mm) ** 2
        else:
            e = model.full_well_e
        noise = NoiseModel.from_sensor(model, e, ref.exposure_ms)
        return float(noise.variance(np.array(MEAN_LEVEL)))

    return var


def build_objective(p: Problem, ref: CameraDesign, n_speeds: int, n_depths: int) -> Objective:
    """The :class:`Objective` over the problem's range, its grid sized for the widest PSF the
    bounds allow."""
    beta = BETA_RANGE * abs(ref.beta_px_per_mm) + ref.focal_length_px * abs(
        1.0 / p.depth_range_mm[0] - 1.0 / p.depth_range_mm[1]
    )
    R_top = 0.95 * ref.R_max_mm if p.free_radius else ref.R_mm
    s = p.max_velocity_px_per_ms
    extent = 2.0 * beta * ref.R_max_mm + s * ref.exposure_ms
    grid = make_grid(s, p.depth_range_mm, n_speeds, n_depths, extent, beta * R_top)
    return Objective(ref, grid, noise_variance(p, ref), p.free_radius)


@dataclass
class Start:
    """One local search: where it began and ended, and its loss (dB) per iteration."""

    index: int
    theta0: np.ndarray
    theta: np.ndarray = None
    worst_db: float = -np.inf
    mean_db: float = -np.inf
    iterations: list = field(default_factory=list)  # (iteration, seconds, soft loss dB)


def start_points(obj: Objective, n_starts: int, seed: int) -> list[np.ndarray]:
    """Start 0: the reference parabola. Others: uniform centres, a focus within 0.5-1.5x the
    reference's beta (same side), and a radius within 0.7-1.3x, from ``seed``."""
    ref = obj.ref
    first = obj.pack(ref.pattern_centres_xy_mm()[:, 0], ref.beta_px_per_mm)
    rng = np.random.default_rng(seed)
    out = [first]
    side = math.copysign(1.0, ref.beta_px_per_mm)
    lo, hi = zip(*obj.bounds())
    for _ in range(n_starts - 1):
        theta = [*rng.uniform(-1.0, 1.0, obj.n), side * rng.uniform(0.5, 1.5)]
        if obj.free_radius:
            theta.append(rng.uniform(0.7, 1.3))
        out.append(np.clip(np.array(theta), lo, hi))
    return out


def local_search(obj: Objective, start: Start, iterations: int, clock, bar=None) -> Start:
    """L-BFGS-B from ``start.theta0`` (exact gradient, box bounds) for ``iterations`` at most."""

    def record(intermediate_result) -> None:
        start.iterations.append(
            (len(start.iterations), clock(), float(intermediate_result.fun))
        )  # fmt: skip
        if bar is not None:
            bar.update()

    loss0 = obj.loss(start.theta0)[0]
    start.iterations.append((0, clock(), float(loss0)))
    res = optimize.minimize(obj.loss, start.theta0, jac=True, method="L-BFGS-B",
                            bounds=obj.bounds(), callback=record,
                            options={"maxiter": iterations})  # fmt: skip
    start.theta = res.x
    p = obj.psnr_db(res.x)
    start.worst_db, start.mean_db = float(p.min()), float(p.mean())
    return start


EVALS_PER_ITERATION = 1.2
"""L-BFGS-B's objective evaluations per iteration, its line search's included: 239 in 198
iterations on ``pacam optimize --max-velocity 1.4`` (43 in 37 with ``--quick``)."""


def _announce(obj: Objective, theta: np.ndarray, iterations: int) -> None:
    """Say the search's longest time on stderr: ``iterations`` of :data:`EVALS_PER_ITERATION`
    evaluations, one evaluation timed now."""

    t0 = time.perf_counter()
    obj.loss(theta)
    each = time.perf_counter() - t0
    say(f"estimate: optimise at most {duration(iterations * EVALS_PER_ITERATION * each)} "
        f"({iterations} iterations of about {EVALS_PER_ITERATION} evaluations of "
        f"{duration(each)}, one timed now); L-BFGS-B stops sooner once it converges (a third "
        "of them on the default problem)")  # fmt: skip


def multi_start(obj: Objective, n_starts: int, iterations: int, seed: int, progress=True):
    """Every start's :class:`Start`, in order; the best is the one with the highest worst case.

    Returns
    -------
    starts : list of Start
    best : Start
    """
    from tqdm import tqdm

    if int(n_starts) != n_starts or n_starts < 1:
        raise ParameterError(f"`starts` must be an integer >= 1, got {n_starts!r}")
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"`iterations` must be an integer >= 1, got {iterations!r}")
    t_begin = time.perf_counter()
    starts = []
    total = n_starts * iterations
    points = start_points(obj, n_starts, seed)
    if progress:
        _announce(obj, points[0], total)
    with tqdm(total=total, desc="optimise", unit="it", disable=not progress, leave=False) as bar:
        for i, th in enumerate(points):
            clock = lambda: time.perf_counter() - t_begin  # noqa: E731 - seconds since the start
            starts.append(local_search(obj, Start(i, th), iterations, clock, bar))
    best = max(starts, key=lambda s: (s.worst_db, s.mean_db))
    return starts, best
