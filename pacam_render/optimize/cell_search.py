"""Gradient search over cell codes (:mod:`.cell_objective`): a binary LCoS code relaxed to
[0, 1] by a sigmoid, A = 1 / (1 + exp(-theta)), climbed with Adam on the mean expected
moving-object PSNR over the training stores, then projected to the LCoS's levels."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .cell_objective import mean_objective

LOGIT_CLIP = 4.0
"""A start's logits: a code's 0 and 1 become -4 and +4 (A = 0.018, 0.982), so that a
start's binary cells can still move."""


@dataclass
class CellSearch:
    """A search's result: the projected code, its and the relaxed code's mean PSNR (dB), and
    per start its (start name, relaxed dB, projected dB); ``rows`` the curve (evaluations,
    seconds, relaxed dB)."""

    code: np.ndarray
    projected_db: float
    relaxed_db: float
    starts: list
    rows: list
    evaluations: int


def project(code, levels: int = 2) -> np.ndarray:
    """``code`` rounded to ``levels`` equally spaced transmittances (2: binary, the
    prototype's ferroelectric LCoS)."""
    if int(levels) != levels or levels < 2:
        raise ParameterError(f"levels: an integer >= 2, got {levels!r}")
    return np.round(np.asarray(code, float) * (levels - 1)) / (levels - 1)


def adam(problems, theta, iterations: int, step: float, rows: list, t0: float):
    """Adam ascent of the mean objective in logits ``theta``; appends to ``rows``."""
    m, v = np.zeros_like(theta), np.zeros_like(theta)
    b1, b2 = 0.9, 0.999
    for i in range(1, iterations + 1):
        a = 1.0 / (1.0 + np.exp(-theta))
        val, g = mean_objective(problems, a)
        g = g * a * (1.0 - a)  # d A / d theta
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        theta = theta + step * (m / (1 - b1**i)) / (np.sqrt(v / (1 - b2**i)) + 1e-12)
        rows.append((len(rows) + 1, time.perf_counter() - t0, val))
    return theta


def gradient_search(problems, starts: dict, iterations: int = 200, step: float = 0.1,
                    levels: int = 2) -> CellSearch:  # fmt: skip
    """Climb from each named start code (n, G, G) in [0, 1]; keep the best projected code.

    Parameters
    ----------
    problems : list of CellProblem
        The training stores (:func:`~.cell_objective.cell_problem`), one cell grid.
    starts : dict
        Name to start code (e.g. the prototype rasterised, random codes).
    iterations : int
        Adam steps per start, each one objective evaluation with its gradient per store.
    step : float
        Adam's step in logits.
    levels : int
        The LCoS's transmittance levels the result is projected to.

    Returns
    -------
    CellSearch
    """
    if int(iterations) != iterations or iterations < 1:
        raise ParameterError(f"iterations: an integer >= 1, got {iterations!r}")
    if not starts:
        raise ParameterError("starts: at least one start code")
    rows, out, best = [], [], None
    t0 = time.perf_counter()
    for name, code in starts.items():
        c = np.clip(np.asarray(code, float), 0.0, 1.0)
        theta = np.where(c >= 0.5, LOGIT_CLIP, -LOGIT_CLIP)  # a binary start
        if np.any((c > 0) & (c < 1)):  # a grey start keeps its levels
            theta = np.log(np.clip(c, 1e-3, 1 - 1e-3) / np.clip(1 - c, 1e-3, 1 - 1e-3))
        theta = adam(problems, theta, int(iterations), step, rows, t0)
        relaxed = 1.0 / (1.0 + np.exp(-theta))
        proj = project(relaxed, levels)
        if not proj.any():
            continue
        r_db = mean_objective(problems, relaxed, False)[0]
        p_db = mean_objective(problems, proj, False)[0]
        out.append((name, r_db, p_db))
        if best is None or p_db > best[0]:
            best = (p_db, r_db, proj)
    if best is None:
        raise ParameterError("every start projected to an all-black code")
    return CellSearch(best[2], best[0], best[1], out, rows, len(rows) * len(problems))
