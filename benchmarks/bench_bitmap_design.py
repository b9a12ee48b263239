"""Whole-aperture bitmaps found on train scenes, checked on held-out scenes (issue 58, item 5).

Train: grey light-field stores of ``family:occluders`` seeds TRAIN (a WINDOW_PX window about
each scene's largest occlusion event, from its card; grey: the designs' question needs no RGB).
Search, with the light fixed at the prototype's: binary bitmaps on CELLS x CELLS cells per
pattern window by gradient (``pacam optimize --space bitmap``'s own functions), scoring the
moving objects' PSNR; one disc per window moving in x and y (``--space discs`` on
DISC_CELLS x DISC_CELLS cells), for each objective (moving alone; its weighted mean in dB with
the still pixels', weight STILL_WEIGHT); the best centres design by the
coordinate search (``--space centres``, the worst case over the stores); the Fourier-model
design (``pacam optimize --max-velocity``, the non-rendered objective) for the same camera
(sensor, lens, LCoS, exposure: the prototype's written as a design file) at the family's
fastest speed and the middle depth; it chooses its own focus, one of its variables. Check:
held-out seeds HELD, FRESH DIRECT renders of every design (new render seeds) and new sensor
draws, scored with the real pipeline (:mod:`pacam_render.optimize.cell_report`), paired 95 %
intervals of the moving-object and still-region PSNR differences against the prototype over
the scenes (each scene's render seeds averaged first: they are not independent). Levin's
camera is focused once for the class, at the family's middle depth (650 mm), as every design
here but the Fourier model's is.

    python benchmarks/bench_bitmap_design.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import record  # noqa: E402

from pacam_render.exposure.direct import render_capture  # noqa: E402
from pacam_render.exposure.plan import plan_capture  # noqa: E402
from pacam_render.exposure.spec import CaptureSpec  # noqa: E402
from pacam_render.lightfield import Store, StoreSpec, render_lightfield, synthesize  # noqa: E402
from pacam_render.model.design_file import write_design  # noqa: E402
from pacam_render.optimize.cell_design import design_spec  # noqa: E402
from pacam_render.optimize.cell_objective import parts  # noqa: E402
from pacam_render.optimize.cell_report import design_row, paired, summary  # noqa: E402
from pacam_render.optimize.cell_run import (  # noqa: E402
    BitmapProblem,
    check_bitmap_problem,
    chosen_design,
    found_design,
    prepare_bitmap,
)
from pacam_render.optimize.rendered_run import RenderedProblem, run_rendered_optimize  # noqa: E402
from pacam_render.optimize.run import run_optimize  # noqa: E402
from pacam_render.optimize.search import Problem  # noqa: E402
from pacam_render.scenes.family import family_scene  # noqa: E402

TRAIN, HELD = tuple(range(8)), tuple(range(10, 20))
DISC_CELLS = 32
"""The discs' soft rasterisation needs the finer grid: the prototype's R is 2.3 cells at 16."""
WINDOW_PX = (128, 64)
"""128 x 64, not 96 x 64: score_capture leaves out +-32 px columns (its shift search at a
1280 px sensor), so a 96 px window scores 32 columns and rarely any still pixel."""
MIDDLE_DEPTH_MM = 650.0
"""The family's depths are 400-900 mm: every camera is focused once for the class here."""
SENSOR, LEVEL = "grasshopper-icx285-mono", 300.0
STILL_WEIGHT = 1.0
"""The still term's weight in (moving + w still) / (1 + w), dB: cell_run's default."""
STORE_PASSES = 4
"""Store passes: the search reads 2, the choice among its results the other 2."""
CHOICES: dict = {}
"""Design name -> the candidate the real pipeline chose (``prototype``: kept)."""
MAX_SPEED_PX_PER_MS = 1.4
"""The family's fastest image speed (its speed range 0.2-1.4 px/ms): the Fourier model's
--max-velocity."""


def window(seed: int) -> tuple[int, int, int, int]:
    """A WINDOW_PX crop centred on the seed's largest occlusion event (its card), inside the
    family's window (480, 360, 320, 240)."""
    card = json.loads((Path(family_scene("occluders", seed)).parent / "scene.json").read_text())
    ev = max(card["occlusion_events"], key=lambda e: e["max_overlap_px"])
    x0, y0, x1, y1 = ev["region_px"]
    w, h = WINDOW_PX
    x = int(np.clip((x0 + x1) / 2 - w / 2, 480, 480 + 320 - w))
    y = int(np.clip((y0 + y1) / 2 - h / 2, 360, 360 + 240 - h))
    return x, y, w, h


def spec(seed: int, spp: int, render_seed: int, passes: int = 2) -> CaptureSpec:
    return CaptureSpec.geometric(scene=f"family:occluders:{seed}", width=1280, height=960,
                                 crop=window(seed), mode="coded", spp=spp, passes=passes,
                                 seed=render_seed, object_depth_mm=MIDDLE_DEPTH_MM,
                                 grey=True)  # fmt: skip


def stores(root: Path, spp: int, train=TRAIN) -> list[str]:
    out = []
    for seed in train:
        folder = root / f"store_{seed}"
        if not (folder / "manifest.json").exists():
            render_lightfield(StoreSpec(spec(seed, spp, 1 + seed, STORE_PASSES), alpha=1.0), folder,
                              progress=False)  # fmt: skip
        Store.open(folder)
        out.append(str(folder))
    return out


def _search(root: Path, name: str, q: BitmapProblem, prepared: dict, found: dict,
            stores) -> None:  # fmt: skip
    """One cell-basis search (``q.space``), chosen with the real pipeline on the stores' held
    passes (``pacam optimize``'s own functions), written as a design file into ``found``."""
    t0 = time.perf_counter()
    f = chosen_design(q, prepared, stores, found_design(q, prepared))
    CHOICES[name] = f["choice"]["chosen"]
    path = root / f"{name.replace(' ', '_').replace('+', '_')}.toml"
    write_design(path, f["design"], True)
    found[name] = (path, time.perf_counter() - t0, f["model_db"]["found"])
    moving, still = parts(prepared["problems"], f["code"])
    print(f"{name}: model {f['model_db']['found']:.2f} dB (moving {moving:.2f}, still "
          f"{still:.2f}), starts {f['model_db']['starts']}; chosen {CHOICES[name]!r}: "
          + ", ".join(f"{k} {v['value_db']:.2f}" for k, v in f["choice"]["scores"].items()),
          flush=True)  # fmt: skip


def designs(root: Path, folders, cells: int, iterations: int, starts: int, quick: bool):
    """Design name -> (design file, seconds, model dB): a bitmap and discs (fixed light; discs
    for each objective), centres and the Fourier model's."""
    found, p = {}, BitmapProblem(tuple(folders), SENSOR, LEVEL, cells, "fixed", starts,
                                 iterations, noise_draws=2)  # fmt: skip
    opened = check_bitmap_problem(p)
    prepared = prepare_bitmap(p, opened)
    _search(root, "bitmap moving", p, prepared, found, opened)
    d = replace(p, space="discs", cells=cells if quick else DISC_CELLS)
    del prepared["bases"], prepared["problems"]  # one grid's bases in memory at a time
    prepared = prepare_bitmap(d, opened)
    _search(root, "discs moving", d, prepared, found, opened)
    still = replace(d, objective="moving+still", still_weight=STILL_WEIGHT)
    _search(root, "discs moving+still", still, prepared, found, opened)
    t0 = time.perf_counter()
    rp = RenderedProblem(tuple(folders), SENSOR, LEVEL, positions=9, sweeps=1, noise_draws=1,
                         check_seeds=0)  # fmt: skip
    doc = run_rendered_optimize(rp, root / "centres", True, progress=False)
    found["centres (worst case)"] = (root / "centres" / "design.toml",
                                     time.perf_counter() - t0, doc["found_worst_db"])  # fmt: skip
    found["fourier model"] = fourier(root, prepared["specs"][0], quick)
    return found, prepared


def fourier(root: Path, base, quick: bool):
    """The Fourier-model design (``pacam optimize --max-velocity``) for ``base``'s camera
    (written as a design file: its sensor, lens, LCoS and exposure), speeds up to
    MAX_SPEED_PX_PER_MS at the middle depth: (design file, seconds, worst-case objective)."""
    t0 = time.perf_counter()
    camera = root / "camera.toml"
    write_design(camera, plan_capture(base).cam, True)
    p = Problem(MAX_SPEED_PX_PER_MS, (MIDDLE_DEPTH_MM, MIDDLE_DEPTH_MM), 16, SENSOR, LEVEL,
                design=str(camera))  # fmt: skip
    doc = run_optimize(p, root / "fourier", quick=quick, seed=0, force=True, progress=False)
    return root / "fourier" / "design.toml", time.perf_counter() - t0, doc["objective_worst"]


def captures(seed: int, spp: int, rseed: int, found: dict):
    """(name, spec) of every design on held-out ``seed`` at render seed ``rseed``."""
    base = spec(seed, spp, rseed)
    out = [("prototype", base)]
    out += [(name, design_spec(base, path)) for name, (path, _, _) in found.items()]
    out.append(("levin (650 mm)", replace(base, mode="levin")))
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a smoke run")
    ap.add_argument("--root", default="/tmp/bench_bitmap_design")
    ap.add_argument("--quiet-stores", action="store_true",
                    help="train on 4 scenes with stores of 4096 spp per pass (render noise "
                    "near 0.3x the sensor's: the camera's regime) and check with 256 spp "
                    "direct renders")  # fmt: skip
    a = ap.parse_args()
    warnings.simplefilter("ignore")  # the family's off-depth notes, once per capture
    store_spp, direct_spp, cells, iters, starts, rseeds = (
        (16, 16, 8, 5, 2, 2) if a.quick else (256, 64, 16, 100, 3, 2)
    )
    train_seeds = TRAIN
    if a.quiet_stores:
        store_spp, direct_spp, train_seeds = 4096, 256, TRAIN[:4]
    root = Path(a.root)
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    folders = stores(root, store_spp, train_seeds)
    t_store = time.perf_counter() - t0
    found, prepared = designs(root, folders, cells, iters, starts, a.quick)
    train = []
    for folder, tpl, sp in zip(folders, prepared["templates"], prepared["specs"]):
        st = Store.open(folder)
        train.append(design_row("prototype", folder, tpl, tpl, SENSOR, LEVEL, (0, 1)))
        for name, (path, _, _) in found.items():
            cap = synthesize(st, design_spec(sp, path), progress=False)
            train.append(design_row(name, folder, cap, tpl, SENSOR, LEVEL, (0, 1)))
    held = []
    for seed in HELD:
        for j in range(rseeds):
            rs = 5000 + 10 * seed + j
            caps = [(n, render_capture(s, progress=False, truth=True))
                    for n, s in captures(seed, direct_spp, rs, found)]  # fmt: skip
            ref = caps[0][1]
            draws = (9000 + rs, 9500 + rs)
            for name, cap in caps:
                held.append(design_row(name, f"{seed}/{rs}", cap, ref, SENSOR, LEVEL, draws,
                                        unit=str(seed)))  # fmt: skip
            print(f"held-out seed {seed} render {j}: done", flush=True)
    diffs = paired(held)
    still = paired(held, "psnr_static_db")
    tr = {r["design"]: r for r in summary(train)}
    rows = []
    for r in summary(held):
        d, e = diffs.get(r["design"]), still.get(r["design"])
        t = tr.get(r["design"])
        f = lambda v: "n/a" if v is None else f"{v:.2f}"  # noqa: E731
        ci = lambda d: "-" if d is None else f"{d[0]:+.2f} [{d[1]:+.2f}, {d[2]:+.2f}] n={d[3]}"  # noqa: E731
        rows.append({
            "design": r["design"],
            "train moving (synth, dB)": f(t and t["psnr_moving_db"]),
            "held moving (dB)": f(r["psnr_moving_db"]), "held still (dB)": f(r["psnr_static_db"]),
            "held whole (dB)": f(r["psnr_db"]),
            "moving vs prototype (95 %)": ci(d), "still vs prototype (95 %)": ci(e),
            "range (px/ms)": f(r["range_px_per_ms"]), "light": f"{r['light_rel']:.2f}x",
        })  # fmt: skip
    (root / "bench.json").write_text(json.dumps({"train": train, "held": held}, indent=1))
    fmt = lambda v: f"{v:.2f}"  # noqa: E731
    notes = (f"train seeds {train_seeds}, held-out {HELD}, {WINDOW_PX[0]}x{WINDOW_PX[1]} windows "
             "at "
             f"each scene's largest occlusion; stores spp {store_spp} x {STORE_PASSES} passes "
             "(the cell searches read 2, the real-pipeline choice among their results and the "
             "prototype the other 2; chosen: "
             + ", ".join(f"{k} -> {v}" for k, v in CHOICES.items()) + ") "
             f"({t_store:.0f} s), grey; bitmap {cells}x{cells} cells, discs {DISC_CELLS}x"
             f"{DISC_CELLS} cells, {starts} starts x {iters} Adam steps each, fixed light, "
             f"objectives moving and (moving + {STILL_WEIGHT:g} still) / {1 + STILL_WEIGHT:g} in "
             "dB; Wiener's prior fitted where |H|^2 >= 0.2; centres 9 positions, 1 sweep; "
             "Fourier model at "
             f"{MAX_SPEED_PX_PER_MS:g} px/ms, {MIDDLE_DEPTH_MM:g} mm, the prototype's camera, "
             "its own focus; model dB (each its own objective): "
             + ", ".join(f"{k} {fmt(v[2])}" for k, v in found.items())
             + f"; held-out: fresh direct renders spp "
             f"{direct_spp} x 2 passes, {rseeds} render seeds per scene, 2 new sensor draws, "
             f"{SENSOR} at {LEVEL:g} photons/px/ms, Wiener; all cameras but the Fourier model's "
             "focused for "
             f"{MIDDLE_DEPTH_MM:g} mm; intervals over scenes (a scene's render seeds averaged "
             "first), the still ones over the scenes whose scored columns hold still pixels; "
             "search s: "
             + ", ".join(f"{k} {v[1]:.0f}" for k, v in found.items())
             + (" (QUICK smoke sizes)" if a.quick else ""))  # fmt: skip
    if a.quick:
        print(rows, notes)
        return
    quiet = ", quiet stores" if a.quiet_stores else ""
    record(f"Whole-aperture designs: train on {len(train_seeds)} family scenes{quiet}, check on "
           f"{len(HELD)} held-out", rows, notes)  # fmt: skip


if __name__ == "__main__":
    main()
