"""The discs design space: in each pattern window one round opening whose centre moves in 2-D
(x and y), one radius R for all windows, searched by gradient on the cells' basis
(:mod:`.cell_objective`) through a soft rasterisation of the discs on the cells.

A disc of centre c_k and radius R covers cell j (centre p_j, pitch h) by about

    A[k, j] = clip(1/2 + (R - |p_j - c_k|) / h, 0, 1)

(the share of the cell inside the disc, linear across one cell's width at the edge): a code on
the cells whose derivative in (c_k, R) is non-zero on the edge cells, so the chain rule takes the
objective's gradient d PSNR / d A to d PSNR / d (c, R). The found design is written as a
``centres`` schedule (``[schedule] centres_mm``, ``[opening] R_mm``), whose captures the store
synthesises and ``pacam render --design`` renders exactly: the rasterisation is the search's
model only.

Every disc stays inside the clear aperture, |c_k| + R <= R_max (projected after each step).
With ``light="fixed"`` R is the store design's (discs inside the lens keep its open area, so
the light is exactly the prototype's); with ``light="free"`` R moves too, from one LCoS pixel
(:data:`~pacam_render.model.camera.MIN_OPENING_LCOS_PX`) to R_max."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..model.camera import MIN_OPENING_LCOS_PX
from .cell_design import cell_centres_mm
from .cell_objective import (
    check_aggregate,
    check_still_weight,
    pooled_objective,
    pooled_objectives,
)
from .cell_search import adam_lockstep, flatten_curves

STEP_CELLS = 0.1
"""Adam's step in cell pitches (mm / pitch): a disc moves about a tenth of a cell a step."""


@dataclass(frozen=True)
class Discs:
    """One disc per pattern window: ``centres_mm`` (n, 2) in the design frame (x right, y
    down), ``R_mm`` the radius, ``is_open`` (n,) the windows the schedule opens."""

    centres_mm: np.ndarray
    R_mm: float
    is_open: np.ndarray


@dataclass(frozen=True)
class DiscGrid:
    """The cell grid the discs are rasterised on: G cells across [-R_max, R_max]."""

    cells: int
    R_max_mm: float
    lcos_pitch_mm: float

    @property
    def pitch_mm(self) -> float:
        return 2.0 * self.R_max_mm / self.cells

    @property
    def R_min_mm(self) -> float:
        return MIN_OPENING_LCOS_PX * self.lcos_pitch_mm


def soft_code(d: Discs, grid: DiscGrid) -> tuple[np.ndarray, dict]:
    """(n, G, G) code of the discs (module docstring), closed windows 0, and what
    :func:`code_vjp` needs."""
    x, y = cell_centres_mm(grid.cells, grid.R_max_mm)
    c = np.asarray(d.centres_mm, float)
    dx = x[None, None, :] - c[:, 0, None, None]
    dy = y[None, :, None] - c[:, 1, None, None]
    dist = np.sqrt(dx * dx + dy * dy) + 1e-12
    t = 0.5 + (d.R_mm - dist) / grid.pitch_mm
    edge = (t > 0) & (t < 1) & np.asarray(d.is_open, bool)[:, None, None]
    code = np.clip(t, 0.0, 1.0) * np.asarray(d.is_open, float)[:, None, None]
    return code, dict(dx=dx, dy=dy, dist=dist, edge=edge)


def code_vjp(g_code: np.ndarray, cache: dict, grid: DiscGrid) -> tuple[np.ndarray, float]:
    """d value / d (centres (n, 2), R) from d value / d code (n, G, G): the chain rule through
    :func:`soft_code`'s edge cells."""
    g = np.where(cache["edge"], g_code, 0.0) / grid.pitch_mm
    gx = np.sum(g * cache["dx"] / cache["dist"], axis=(1, 2))
    gy = np.sum(g * cache["dy"] / cache["dist"], axis=(1, 2))
    return np.stack([gx, gy], axis=1), float(np.sum(g))


def project_inside(d: Discs, grid: DiscGrid, free_radius: bool) -> Discs:
    """Every disc inside the clear aperture: R in [R_min, R_max] (when free), then each centre
    pulled towards the axis to |c| <= R_max - R; closed windows' centres at the axis."""
    R = float(np.clip(d.R_mm, grid.R_min_mm, grid.R_max_mm)) if free_radius else d.R_mm
    c = np.asarray(d.centres_mm, float).copy()
    reach = max(grid.R_max_mm - R, 0.0)
    norm = np.hypot(c[:, 0], c[:, 1])
    far = norm > reach
    c[far] *= (reach / np.maximum(norm[far], 1e-300))[:, None]
    c[~np.asarray(d.is_open, bool)] = 0.0
    return Discs(c, R, d.is_open)


def disc_objective(problems, d: Discs, grid: DiscGrid, grad: bool = True,
                   still_weight: float = 0.0, aggregate: str = "mean"):  # fmt: skip
    """The objective (dB) of the discs' soft code pooled over the stores
    (:func:`~.cell_objective.pooled_objectives`), and its gradient in (centres, R) when
    ``grad``."""
    code, cache = soft_code(d, grid)
    val, g = pooled_objective(problems, code, grad, still_weight, aggregate)
    return val, (None if g is None else code_vjp(g, cache, grid))


@dataclass
class DiscSearch:
    """A search's result: the best discs, their mean model dB, per start (name, dB), the curve
    ``rows`` (evaluation, seconds, dB), the evaluations over all stores and each start's
    discs (``found``: start name to discs)."""

    discs: Discs
    model_db: float
    starts: list
    rows: list
    evaluations: int
    found: dict


def random_discs(rng, base: Discs, grid: DiscGrid) -> Discs:
    """Centres drawn uniformly over the disc of radius R_max - R (the base's radius)."""
    reach = max(grid.R_max_mm - base.R_mm, 0.0)
    n = len(base.is_open)
    r = reach * np.sqrt(rng.random(n))
    phi = 2 * np.pi * rng.random(n)
    c = np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)
    return project_inside(Discs(c, base.R_mm, base.is_open), grid, False)


def _climb(problems, starts: list, grid: DiscGrid, iterations: int, free: bool, t0: float,
           still_weight: float, aggregate: str):  # fmt: skip
    """All starts' projected Adam ascent in (centres, R) together (one evaluation of every
    start's soft code per step, :func:`~.cell_search.adam_lockstep`): the climbed discs and
    each start's curve."""
    is_open = starts[0].is_open
    n = len(is_open)

    def discs(x) -> Discs:
        return Discs(x[:-1].reshape(n, 2), float(x[-1]), is_open)

    def value_grad(xs):
        codes, caches = zip(*(soft_code(discs(x), grid) for x in xs))
        vals, g = pooled_objectives(problems, np.stack(codes), True, still_weight, aggregate)
        out = np.zeros_like(xs)
        for i, (gi, cache) in enumerate(zip(g, caches)):
            gc, gR = code_vjp(gi, cache, grid)
            out[i] = np.concatenate([gc.ravel(), [gR if free else 0.0]])
        return vals, out

    def project(xs):
        got = [project_inside(discs(x), grid, free) for x in xs]
        return np.stack([np.concatenate([d.centres_mm.ravel(), [d.R_mm]]) for d in got])

    x0 = project(np.stack([np.concatenate([np.ravel(d.centres_mm), [d.R_mm]]) for d in starts]))
    xs, curves = adam_lockstep(x0, value_grad, project, iterations, STEP_CELLS * grid.pitch_mm,
                               t0)  # fmt: skip
    return [discs(x) for x in xs], curves


def disc_search(problems, starts: dict, grid: DiscGrid, iterations: int = 200,
                light: str = "fixed", still_weight: float = 0.0,
                aggregate: str = "mean") -> DiscSearch:  # fmt: skip
    """Climb from each named start (:class:`Discs`); keep the discs of the best model dB.

    Parameters
    ----------
    problems : list of CellProblem
        The training stores (:func:`~.cell_objective.cell_problem`) on ``grid``'s cells.
    starts : dict
        Name to start discs (e.g. the prototype's parabola, random centres).
    grid : DiscGrid
        The cells the discs are rasterised on.
    iterations : int
        Adam steps per start, each one objective evaluation with its gradient per store.
    light : {"fixed", "free"}
        Whether R stays the starts' (the store design's light) or moves.
    still_weight : float
        The still pixels' weight (:func:`~.cell_objective.objective`); 0 scores moving only.
    aggregate : {"mean", "worst"}
        How the stores' scores are pooled (:func:`~.cell_objective.pooled_objectives`).

    Returns
    -------
    DiscSearch
    """
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"iterations: an integer >= 1, got {iterations!r}")
    if light not in ("fixed", "free"):
        raise ParameterError(f"light: one of fixed, free, got {light!r}")
    if not starts:
        raise ParameterError("starts: at least one start")
    sw = check_still_weight(problems, still_weight)
    check_aggregate(aggregate)
    t0 = time.perf_counter()
    names = list(starts)
    found, curves = _climb(problems, [starts[k] for k in names], grid, int(iterations),
                           light == "free", t0, sw, aggregate)  # fmt: skip
    vals = [disc_objective(problems, d, grid, False, sw, aggregate)[0] for d in found]
    best = int(np.argmax(vals))
    rows = flatten_curves(curves)
    return DiscSearch(found[best], vals[best], list(zip(names, vals)), rows,
                      len(rows) * len(problems), dict(zip(names, found)))  # fmt: skip


def disc_design(plan, d: Discs, name: str = "pacam optimize --space discs"):
    """The base design of ``plan`` at its full sensor size with the discs as a ``centres``
    schedule and R as its opening."""
    full = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px)
    return full.with_(pattern_centres_mm=tuple((float(x), float(y)) for x, y in d.centres_mm),
                      R_mm=float(d.R_mm), pattern_masks=None, quoted_a_i_px_per_ms2=None,
                      name=name)  # fmt: skip


def plan_discs(plan) -> Discs:
    """``plan``'s own design as discs (its centres, its R, the windows its schedule opens)."""
    cam = plan.cam
    if cam.pattern_masks is not None:
        raise ParameterError("the discs space starts from a disc schedule; this design is a bitmap")
    is_open = np.asarray(plan.aperture(plan.sensor_params()).is_open, bool)
    return Discs(np.asarray(cam.pattern_centres_xy_mm(), float), float(cam.R_mm), is_open)
