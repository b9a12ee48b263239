"""Gradient search over cell codes (:mod:`.cell_objective`): a binary LCoS code relaxed to
[0, 1], climbed with Adam on the expected moving-object PSNR pooled over the training stores
(their mean, or the soft minimum of their gains, ``aggregate``; or its weighted mean with the
still pixels', ``still_weight``), then projected to the
LCoS's levels.

``light="free"``: the code is A = 1 / (1 + exp(-theta)), Adam in the logits theta; the total
light (open area x time) is whatever the search finds, and more light is less sensor noise, so
a design may win by collecting light alone.

``light="fixed"``: the code keeps the total light L(A) = sum_kc lambda_kc A_kc (:func:`light`)
equal to a reference's (the prototype's disc, rasterised). Projected Adam in A itself: after
each step A is the Euclidean projection onto {0 <= A <= 1, L(A) = L_ref} (:func:`project_light`,
exact: A = clip(A' - nu lambda, 0, 1) with nu found by bisection). A projection, not a penalty:
the constraint is one linear equality in a box, its projection is exact and cheap, it holds at
every step, and there is no penalty weight to tune that would trade light against PSNR. The
binary code keeps it too (:func:`project_levels`: the highest cells opened until the light is
nearest the reference, within one cell-window's light, 1 / (16 x ~800) of the lens's)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .cell_objective import (
    check_aggregate,
    check_still_weight,
    pooled_objective,
    pooled_objectives,
)

LOGIT_CLIP = 4.0
"""A start's logits: a code's 0 and 1 become -4 and +4 (A = 0.018, 0.982), so that a
start's binary cells can still move."""


@dataclass
class CellSearch:
    """A search's result: the projected code, its and the relaxed code's mean PSNR (dB), and
    per start its (start name, relaxed dB, projected dB); ``rows`` the curve (evaluations,
    seconds, relaxed dB); ``codes`` each start's projected code (start name to code)."""

    code: np.ndarray
    projected_db: float
    relaxed_db: float
    starts: list
    rows: list
    evaluations: int
    codes: dict


def _check_levels(levels) -> int:
    if int(levels) != levels or levels < 2:
        raise ParameterError(f"levels: an integer >= 2, got {levels!r}")
    return int(levels)


def project(code, levels: int = 2) -> np.ndarray:
    """``code`` rounded to ``levels`` equally spaced transmittances (2: binary, the
    prototype's ferroelectric LCoS)."""
    n = _check_levels(levels) - 1
    return np.round(np.asarray(code, float) * n) / n


LIGHT_CHOICES = ("free", "fixed")


def light_of(problem, code) -> float:
    """The code's light factor L: open area x time over pi R_max^2 x T (the objective's,
    :func:`~.cell_objective.sigma2`'s L, the LCoS's contrast floor left out)."""
    a = np.asarray(code, float)[:, problem.cells_ij[:, 0], problem.cells_ij[:, 1]]
    return float(np.sum(a * problem.lam))


def _lam_grid(problem, shape) -> np.ndarray:
    """lambda_kc on the (n, G, G) grid, 0 on cells no lens point reaches."""
    out = np.zeros(shape)
    out[:, problem.cells_ij[:, 0], problem.cells_ij[:, 1]] = problem.lam
    return out


def project_light(code, problem, target: float) -> np.ndarray:
    """The Euclidean projection of ``code`` onto {0 <= A <= 1, L(A) = target}: A = clip(code -
    nu lambda, 0, 1), nu by bisection (L falls with nu); off-lens cells 0."""
    lam = _lam_grid(problem, np.shape(code))
    a = np.where(lam > 0, np.asarray(code, float), 0.0)
    if not 0.0 < target < lam.sum():
        raise ParameterError(
            f"light: a target in (0, {lam.sum():.4g}) (the whole lens), got {target!r}"
        )
    x = a / np.where(lam > 0, lam, 1.0)
    lo, hi = float(np.min(x[lam > 0])) - 1.0 / lam[lam > 0].min(), float(np.max(x[lam > 0]))
    for _ in range(100):  # L(nu) is monotone: 100 halvings reach float64's resolution
        nu = 0.5 * (lo + hi)
        lo, hi = (nu, hi) if np.sum(np.clip(a - nu * lam, 0, 1) * lam) > target else (lo, nu)
    return np.where(lam > 0, np.clip(a - 0.5 * (lo + hi) * lam, 0.0, 1.0), 0.0)


def project_levels(code, problem, target: float, levels: int = 2) -> np.ndarray:
    """``code`` on ``levels`` equal transmittance steps at the light nearest ``target``: each
    cell floored to a step, then the cells with the largest remainders raised one step each,
    as many as bring L nearest the target."""
    step = 1.0 / (_check_levels(levels) - 1)
    lam = _lam_grid(problem, np.shape(code))
    a = np.where(lam > 0, np.asarray(code, float), 0.0)
    low = np.floor(a / step + 1e-12) * step
    rest = np.where((lam > 0) & (low < 1.0), a - low, -np.inf).ravel()
    order = np.argsort(-rest, kind="stable")
    order = order[np.isfinite(rest[order])]
    gained = np.concatenate([[0.0], np.cumsum(step * lam.ravel()[order])])
    count = int(np.argmin(np.abs(float(np.sum(low * lam)) + gained - target)))
    out = low.ravel().copy()
    out[order[:count]] += step
    return out.reshape(low.shape)


def adam_lockstep(x, value_grad, project, iterations: int, step: float, t0: float):
    """Adam ascent of S starts at once (``x``: (S, ...)), one shared evaluation per step
    (``value_grad(x)`` -> values (S,), gradients like x: the basis read once for all starts),
    ``project`` applied after each step.

    Returns
    -------
    (ndarray, list)
        The climbed x, and per start its curve [(iteration, seconds, value), ...].
    """
    m, v = np.zeros_like(x), np.zeros_like(x)
    b1, b2 = 0.9, 0.999
    curves = [[] for _ in range(len(x))]
    for i in range(1, iterations + 1):
        val, g = value_grad(x)
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        x = project(x + step * (m / (1 - b1**i)) / (np.sqrt(v / (1 - b2**i)) + 1e-12))
        now = time.perf_counter() - t0
        for s, c in zip(val, curves):
            c.append((i, now, float(s)))
    return x, curves


def _target(problem, reference) -> float:
    """The light a fixed-light search keeps: ``reference``'s, a code or a light factor."""
    if np.ndim(reference) == 0:
        return float(reference)
    return light_of(problem, reference)


def _climb(problems, codes, iterations, step, t0, target, still_weight, aggregate):
    """All starts climbed together: the relaxed codes (free light: Adam in logits; fixed:
    projected Adam in the code) and each start's curve."""
    c = np.clip(np.asarray(codes, float), 0.0, 1.0)
    if target is not None:

        def fixed(a):
            return np.stack([project_light(x, problems[0], target) for x in a])

        def value_grad(a):
            return pooled_objectives(problems, a, True, still_weight, aggregate)

        return adam_lockstep(fixed(c), value_grad, fixed, iterations, step, t0)
    theta = np.where(c >= 0.5, LOGIT_CLIP, -LOGIT_CLIP)  # a binary start
    grey = np.any((c > 0) & (c < 1), axis=tuple(range(1, c.ndim)))  # a grey start keeps levels
    logits = np.log(np.clip(c, 1e-3, 1 - 1e-3) / np.clip(1 - c, 1e-3, 1 - 1e-3))
    theta[grey] = logits[grey]

    def value_grad_logits(t):
        a = 1.0 / (1.0 + np.exp(-t))
        val, g = pooled_objectives(problems, a, True, still_weight, aggregate)
        return val, g * a * (1.0 - a)  # d A / d theta

    theta, curves = adam_lockstep(theta, value_grad_logits, lambda t: t, iterations, step, t0)
    return 1.0 / (1.0 + np.exp(-theta)), curves


def flatten_curves(curves) -> list:
    """Per-start curves as one list of rows (evaluation, seconds, value), start after start
    (the starts climbed together, so the seconds are shared)."""
    rows = []
    for c in curves:
        rows += [(len(rows) + 1, t, v) for _, t, v in c]
    return rows


def gradient_search(problems, starts: dict, iterations: int = 200, step: float | None = None,
                    levels: int = 2, light: str = "free", reference=None,
                    still_weight: float = 0.0, aggregate: str = "mean") -> CellSearch:  # fmt: skip
    """Climb from each named start code (n, G, G) in [0, 1]; keep the best projected code.

    Parameters
    ----------
    problems : list of CellProblem
        The training stores (:func:`~.cell_objective.cell_problem`), one cell grid.
    starts : dict
        Name to start code (e.g. the prototype rasterised, random codes).
    iterations : int
        Adam steps per start, each one objective evaluation with its gradient per store.
    step : float, optional
        Adam's step: in logits with free light (default 0.1), in transmittance with fixed
        light (default 0.02).
    levels : int
        The LCoS's transmittance levels the result is projected to.
    light : {"free", "fixed"}
        Whether the code's total light is free or held at ``reference``'s (module docstring).
    reference : ndarray or float, optional
        With fixed light, the code whose light (:func:`light_of`) every code keeps, or that
        light itself (e.g. the prototype's capture's ``record.light_factor``: its disc, not
        the disc rasterised on the cells).
    still_weight : float
        0: the moving objects' PSNR alone; w > 0: the weighted mean (P + w P_s) / (1 + w) with
        the still pixels' (:func:`~.cell_objective.objective`).
    aggregate : {"mean", "worst"}
        How the stores' scores are pooled (:func:`~.cell_objective.pooled_objectives`).

    Returns
    -------
    CellSearch
    """
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"iterations: an integer >= 1, got {iterations!r}")
    if light not in LIGHT_CHOICES:
        raise ParameterError(f"light: one of {', '.join(LIGHT_CHOICES)}, got {light!r}")
    if light == "fixed" and reference is None:
        raise ParameterError("reference: fixed light needs the code whose light it keeps")
    _check_levels(levels)
    sw = check_still_weight(problems, still_weight)
    check_aggregate(aggregate)
    if not starts:
        raise ParameterError("starts: at least one start code")
    target = None if light == "free" else _target(problems[0], reference)
    step = (0.1 if target is None else 0.02) if step is None else float(step)
    out, best, codes = [], None, {}
    t0 = time.perf_counter()
    names = list(starts)
    relaxed, curves = _climb(problems, np.stack([starts[n] for n in names]), int(iterations),
                             step, t0, target, sw, aggregate)  # fmt: skip
    for name, r in zip(names, relaxed):
        proj = project(r, levels) if target is None else project_levels(
            r, problems[0], target, levels)  # fmt: skip
        if not proj.any():
            continue
        r_db = pooled_objective(problems, r, False, sw, aggregate)[0]
        p_db = pooled_objective(problems, proj, False, sw, aggregate)[0]
        out.append((name, r_db, p_db))
        codes[name] = proj
        if best is None or p_db > best[0]:
            best = (p_db, r_db, proj)
    if best is None:
        raise ParameterError("every start projected to an all-black code")
    rows = flatten_curves(curves)
    return CellSearch(best[2], best[0], best[1], out, rows, len(rows) * len(problems), codes)
