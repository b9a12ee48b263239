"""The found design chosen with the real pipeline: every start's result of a cell-basis search
(:mod:`.cell_run`) and the store's own design, synthesised from each training store and scored
as the report scores them (:func:`~.cell_report.design_row`), and the best kept.

The model (:mod:`.cell_objective`) ranks designs well enough to climb, not to choose: it leaves
out the scorer's per-object shifts, the per-capture prior fit and drawn noise. So the last word
is the real pipeline's, on the training stores only (the held-out stay unseen), and on passes
the search did not read where the stores have enough (a search fits its samples' Monte Carlo
noise: 0.6 of a bitmap's 2.3 dB on its own samples, ``bench_bitmap_design.py``): the score is the
same aggregate the search climbs (the moving objects' PSNR, or its weighted mean in dB with
the still regions', pooled over the stores as the search pools it: their mean, or the soft
minimum of the gains over the store's design), and with ``max_still_loss_db`` a candidate whose
still regions lose more than that against the store's design (mean over the stores that show
still pixels) is not eligible. Where no candidate beats the store's design, it is kept: a
search never hands back a design worse than its start on what it was trained on."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..lightfield.synthesis import synthesize
from ..model.design_file import write_design
from .cell_design import design_spec
from .cell_objective import soft_minimum
from .cell_report import design_row

PROTOTYPE = "prototype"
"""The store's own design's name among the candidates."""
MIN_SIDE_PASSES = 2
"""Passes on each side of a split (search, choice): a capture's Monte Carlo sigma needs two."""


def split_passes(p, stores) -> tuple[tuple[int, ...] | None, tuple | None]:
    """(search passes, choice passes) of every store: with ``held_passes`` K the last K passes
    of each store choose and the others search; default (None) half of them where every store
    has at least 2 x MIN_SIDE_PASSES, else none held (both None: all passes do both)."""
    n = min(s.manifest.passes for s in stores)
    k = p.held_passes
    if k is None:
        k = n // 2 if n >= 2 * MIN_SIDE_PASSES else 0
    if k == 0:
        return None, None
    if not (MIN_SIDE_PASSES <= k <= n - MIN_SIDE_PASSES):
        raise ParameterError(
            f"held_passes: 0, or {MIN_SIDE_PASSES} to the stores' fewest passes ({n}) - "
            f"{MIN_SIDE_PASSES} (each side needs {MIN_SIDE_PASSES} for its Monte Carlo sigma), "
            f"got {k}"
        )
    return tuple(range(n - k)), tuple(range(n - k, n))


def aggregate(rows: list[dict], still_weight: float) -> tuple[float, float | None, float]:
    """(moving, still, value) of one design's rows: the moving PSNR's mean over the stores that
    score one (-inf where none does: the scorer's columns hold no moving object), the still
    PSNR's over those that have one (None where none has), and the score the search climbs,
    (moving + w still) / (1 + w) (moving alone where w = 0 or no still)."""
    got = [r["psnr_moving_db"] for r in rows if r["psnr_moving_db"] is not None]
    moving = float(np.mean(got)) if got else -math.inf  # no store scores a moving object
    got = [r["psnr_static_db"] for r in rows if r["psnr_static_db"] is not None]
    still = float(np.mean(got)) if got else None
    if still_weight == 0 or still is None:
        return moving, still, moving
    return moving, still, (moving + still_weight * still) / (1.0 + still_weight)


def worst_value(rows: list[dict], name: str, still_weight: float) -> float:
    """The "worst" aggregate of design ``name``'s rows, as the search pools its model
    (:func:`~.cell_objective.pooled_objectives`): the store's design's mean score plus the
    soft minimum over the stores of ``name``'s gain over it there (stores that score a moving
    object)."""

    def per_store(design):
        return {r["where"]: aggregate([r], still_weight)[2] for r in rows
                if r["design"] == design and r["psnr_moving_db"] is not None}  # fmt: skip

    ref, got = per_store(PROTOTYPE), per_store(name)
    where = [w for w in ref if w in got]
    if not where:
        return -math.inf
    gains = np.array([got[w] - ref[w] for w in where])
    return float(np.mean([ref[w] for w in where]) + soft_minimum(gains)[0])


def choose(candidates: dict, stores, specs, templates, p, passes=None) -> dict:
    """Score each candidate (name to its CameraDesign) and the store's design on the training
    stores with the real pipeline and choose.

    Parameters
    ----------
    candidates : dict
        Start name to the design that start's search found.
    stores, specs, templates : list
        The training stores, their captures (the store's design, the problem's optics) and
        those captures synthesised.
    p : BitmapProblem
        The sensor, light level, noise draws, still weight and ``max_still_loss_db``.
    passes : sequence of int, optional
        The store passes the candidates are synthesised from (``templates`` must be too): the
        ones the search did not read, so that its fit to its samples' noise does not choose.

    Returns
    -------
    dict
        ``chosen`` (a candidate's name, or :data:`PROTOTYPE` where none beat it), ``rows``
        (every design's report rows on every store), ``scores`` (name to moving, still, value
        and whether eligible).
    """
    with tempfile.TemporaryDirectory(prefix="pacam-candidates-") as tmp:
        paths = {}
        for i, (name, design) in enumerate(candidates.items()):
            paths[name] = Path(tmp) / f"candidate_{i}.toml"
            write_design(paths[name], design, force=True)
        rows = score_rows(p, p.stores, stores, specs, templates, paths, passes)
    return _pick(rows, [PROTOTYPE, *candidates], p.weight, p.max_still_loss_db, p.aggregate)


def score_rows(p, folders, stores, specs, templates, paths: dict, passes=None) -> list[dict]:
    """Report rows (:func:`~.cell_report.design_row`) of each store's own design (its
    ``templates``, named :data:`PROTOTYPE`) and of each design file in ``paths`` (name to
    path), synthesised from each store (its ``passes``), store by store."""
    draws, rows = tuple(range(p.noise_draws)), []
    for folder, store, spec, tpl in zip(folders, stores, specs, templates):
        rows.append(design_row(PROTOTYPE, str(folder), tpl, tpl, p.sensor, p.light_level, draws))
        for name, path in paths.items():
            cap = synthesize(store, design_spec(spec, path), progress=False, passes=passes)
            rows.append(design_row(name, str(folder), cap, tpl, p.sensor, p.light_level, draws))
    return rows


def _pick(rows: list[dict], names: list[str], weight: float, max_loss: float | None,
          pool: str = "mean") -> dict:  # fmt: skip
    """The eligible design of the best score (pooled over the stores as the search pooled it,
    ``pool``); the store's design where none beats it."""
    scores = {}
    for name in names:
        moving, still, value = aggregate([r for r in rows if r["design"] == name], weight)
        if pool == "worst":
            value = worst_value(rows, name, weight)
        scores[name] = {"moving_db": moving, "still_db": still, "value_db": value}
    ref = scores[PROTOTYPE]
    for s in scores.values():
        s["eligible"] = (max_loss is None or s["still_db"] is None or ref["still_db"] is None
                         or s["still_db"] >= ref["still_db"] - max_loss)  # fmt: skip
    ok = [n for n in names if scores[n]["eligible"]]
    chosen = max(ok, key=lambda n: (scores[n]["value_db"], n == PROTOTYPE))
    return {"chosen": chosen, "rows": rows, "scores": scores}
