"""``pacam optimize`` end to end: pose the problem, search, and write every result."""

from __future__ import annotations

import time
from pathlib import Path

from ..model.design import solve
from ..model.design_file import write_design
from .outputs import (
    designed_camera,
    plot_all,
    schedule_document,
    write_bitmaps,
    write_report,
    write_schedule_json,
)
from .search import Problem, build_objective, multi_start, reference_design

SCALE = {False: dict(n_speeds=33, n_depths=5, starts=6, iterations=100),
         True: dict(n_speeds=17, n_depths=3, starts=2, iterations=30)}  # fmt: skip
"""Grid and search sizes: full, and ``--quick``."""


def _parabola(problem: Problem, obj, R_mm: float) -> dict:
    """The paper's parabola at the optimised schedule's light (its opening R), scored alike."""
    ref = obj.ref
    if abs(R_mm - ref.R_mm) > 1e-12 * ref.R_mm:  # a free radius: the parabola at equal light
        ref = solve(problem.max_velocity_px_per_ms, object_depth_mm=ref.object_depth_mm,
                    f_number=ref.F_min * ref.R_max_mm / R_mm, base=ref)  # fmt: skip
    X = ref.pattern_centres_xy_mm()[:, 0]
    theta = obj.pack(X, ref.beta_px_per_mm, R_mm)
    p = obj.psnr_db(theta)
    full = ref.summary()
    summary = {k: full[k] for k in ("R_mm", "focus_distance_mm", "r_px", "a_i_px_per_ms2")}
    summary["centres_mm"] = [[float(x), 0.0] for x in X]
    return dict(worst=float(p.min()), mean=float(p.mean()), psnr=p, design=summary,
                camera=ref, theta=theta, theta_X=X)  # fmt: skip


def run_optimize(problem: Problem, out: Path, *, quick: bool, seed: int, force: bool,
                 starts: int | None = None, iterations: int | None = None,
                 progress: bool = True) -> dict:  # fmt: skip
    """Optimise, then write schedule.json, design.toml (the designed camera, which every
    command takes with ``--design``), lcos/, the plots and report.md into ``out``.

    Returns
    -------
    dict
        The schedule.json object.
    """
    sc = dict(SCALE[quick])
    sc["starts"] = starts or sc["starts"]
    sc["iterations"] = iterations or sc["iterations"]
    ref = reference_design(problem)
    obj = build_objective(problem, ref, sc["n_speeds"], sc["n_depths"])
    t0 = time.perf_counter()
    found, best = multi_start(obj, sc["starts"], sc["iterations"], seed, progress)
    seconds = time.perf_counter() - t0
    parabola = _parabola(problem, obj, obj.unpack(best.theta)[2])
    run = dict(seed=seed, starts=sc["starts"], iterations=sc["iterations"], seconds=seconds,
               quick=quick, best_start=best.index)  # fmt: skip
    doc = schedule_document(problem, obj, best, parabola, run)
    write_schedule_json(out, doc, force)
    cam = designed_camera(obj, best.theta)
    write_bitmaps(out, cam, force)
    write_design(out / "design.toml", cam.with_(name="pacam optimize"), force)
    plot_all(out, obj, best, parabola, found, force)
    write_report(out, doc, found, force)
    return doc
