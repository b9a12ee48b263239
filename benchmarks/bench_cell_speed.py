"""How fast the cell objective climbs (issue 58, "Fast"): objective evaluations with their
gradient per second on a 32x32-cell, 16-window code of a 96x64 window, on this machine's cores.

One light-field store of the train window (grey and RGB), its cell basis (G = 32, the default),
the objective of :mod:`pacam_render.optimize.cell_objective` (moving objects' PSNR; and with
the still term) timed on a random grey code, value and gradient, after a warm-up; the discs
space (:mod:`pacam_render.optimize.disc_space`) adds its soft rasterisation and chain rule.
``10^4 evals`` projects a search of 10^4 evaluations (the issue's bar: 10 minutes at most).

    python benchmarks/bench_cell_speed.py
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from common import median_spread, record, timeit

from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.optimize.cell_design import disc_code
from pacam_render.optimize.cell_objective import cell_problem, objective, objectives
from pacam_render.optimize.disc_space import DiscGrid, disc_objective, plan_discs

CROP = (440, 400, 96, 64)
STARTS = (4, 8)
"""Starts that climb together: ``pacam optimize``'s default for a cell search, and ``--starts
8`` (the basis is read once per step for all: the marginal start costs its FFTs alone)."""
SENSOR = {True: "grasshopper-icx285-mono", False: "grasshopper-icx285"}


def _timings(grey: bool, cells: int) -> list[dict]:
    """The three objectives' timings on one store (grey or RGB)."""
    spec = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=CROP, mode="coded",
                                 grey=grey, spp=64, passes=2, seed=1)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        store = render_lightfield(StoreSpec(spec, alpha=1.0), Path(tmp) / "s", progress=False)
        plan = plan_capture(spec)
        basis = cell_basis(store, spec, cells)
        tpl = synthesize(store, spec, progress=False)
        base = disc_code(plan, cells)
        p = cell_problem(basis, tpl, plan, base, SENSOR[grey], 300.0)
    code = np.random.default_rng(0).uniform(0.05, 0.95, base.shape)
    grid = DiscGrid(cells, plan.cam.R_max_mm, plan.cam.lcos_pitch_mm)
    discs = plan_discs(plan)
    many = {n: np.random.default_rng(n).uniform(0.05, 0.95, (n,) + base.shape) for n in STARTS}
    cases = {  # name: (call, codes it evaluates)
        "bitmap, moving": (lambda: objective(p, code, True), 1),
        "bitmap, moving + still": (lambda: objective(p, code, True, 1.0), 1),
        "discs, moving": (lambda: disc_objective([p], discs, grid, True), 1),
        **{
            f"bitmap, moving, {n} starts together": (lambda n=n: objectives(p, many[n], True), n)
            for n in STARTS
        },
    }
    rows = []
    for name, (fn, count) in cases.items():
        med, spread = median_spread(timeit(fn, repeat=20, warmup=2))
        med, spread = med / count, spread / count
        rows.append({"channels": "grey" if grey else "RGB", "objective": name,
                     "ms / eval (median)": round(1e3 * med, 2), "+-": round(1e3 * spread, 2),
                     "evals / s": round(1.0 / med, 1), "10^4 evals (min)": round(1e4 * med / 60, 2),
                     "basis MiB": round(basis.images.nbytes / 2**20, 1)})  # fmt: skip
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, default=32)
    a = ap.parse_args()
    rows = _timings(True, a.cells) + _timings(False, a.cells)
    record(f"Cell objective speed: {a.cells}x{a.cells} cells, 16 windows, 96x64 window", rows,
           "one objective evaluation with its gradient on one store (a search's evaluation "
           "is one per training store; 'starts together': the starts climb in lockstep, the "
           "basis read once per step for all, time per code), the median of 20 after 2 "
           "warm-ups; train window "
           f"{CROP}, store 64 spp x 2 passes, alpha 1")  # fmt: skip


if __name__ == "__main__":
    main()
