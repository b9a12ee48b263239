"""How many training scenes a whole-aperture design needs: held-out gain against N (issue 58).

The bitmap searched on 4 or 8 family scenes gained +1.7 to +2.6 dB on those scenes' unread
store passes and nothing on held-out ones (``bench_bitmap_design.py``). Is that the search
fitting its few scenes (then more scenes close the gap), or the prototype being near the best
this camera can do for the class at its light (then they do not)? This runs the same bitmap
search (fixed light, moving objects' PSNR, 3 starts x 100 Adam steps, ``pacam optimize --space
bitmap``'s own functions) on the first N of TRAIN_SEEDS for each N in COUNTS, on CELLS x CELLS
cells for each CELLS in GRIDS (fewer cells: fewer degrees of freedom), and checks every search's
best candidate on the same 10 held-out scenes as ``bench_bitmap_design.py``: fresh direct
renders, new render seeds, new sensor draws, paired 95 % intervals against the prototype.

"Best candidate" is the start whose result scores highest on the training stores' unread passes
(the real pipeline): what the search learnt, whether or not ``pacam optimize``'s choice would
have kept the prototype (the table says which it chose).

    python benchmarks/bench_design_scenes.py [--quick] [--root DIR] [--store-spp SPP]
        [--counts N ...] [--grids G ...]

``--store-spp`` above the default 256 quietens the stores (render noise falls as
1/sqrt(spp); at 256 it is 1-2x the sensor's at 300 photons/px/ms): a separate ``--root``, and
its own RESULTS.md section.

``--noise-ratio R`` renders every checked capture to a Monte Carlo sigma of at most R x the
sensor's noise instead of a fixed spp. At a fixed spp a bitmap's captures keep 2-3x the
prototype's render noise (its open cells are scattered over the lens, so a pixel's rays reach
more of the scene), which counts against it; the table's "render noise / sensor" column says
what each design reached. ``--designs-from A.json B.json --only TEXT ...`` checks earlier runs'
designs (no search); ``--baselines`` adds ``bench_bitmap_design.py``'s best centres design and
Fourier-model design from the root.
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import time
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_bitmap_design as bbd  # noqa: E402
from common import record  # noqa: E402

from pacam_render.exposure.direct import render_capture  # noqa: E402
from pacam_render.model.design_file import write_design  # noqa: E402
from pacam_render.optimize.cell_design import design_spec  # noqa: E402
from pacam_render.optimize.cell_objective import AGGREGATES, WORST_SOFTNESS_DB  # noqa: E402
from pacam_render.optimize.cell_report import design_row, paired, summary  # noqa: E402
from pacam_render.optimize.cell_run import (  # noqa: E402
    CELL_SPACES,
    BitmapProblem,
    check_bitmap_problem,
    chosen_design,
    found_over_focus,
    prepare_bitmap,
)
from pacam_render.optimize.cell_select import PROTOTYPE  # noqa: E402
from pacam_render.optimize.rendered_run import store_noise  # noqa: E402
from pacam_render.sensor.apply import SensorTarget  # noqa: E402
from pacam_render.sensor.model import SensorModel  # noqa: E402

TRAIN_SEEDS = tuple(s for s in range(42) if s not in bbd.HELD)
"""Family seeds 0-9 and 20-41: never a held-out one (10-19)."""
COUNTS = (4, 8, 16, 32)
GRIDS = (16, 8)
STARTS, ITERATIONS = 3, 100
HELD_SEEDS = bbd.HELD + tuple(range(42, 62))
"""30 held-out scenes: bench_bitmap_design.py's 10 and 20 more. A design's gain varies from
scene to scene by +-2 dB, so 10 scenes resolve only about +-1.2 dB."""
RENDER_SEEDS = 1
"""A scene's second render seed moved its differences by 0.05 dB: scenes, not seeds, count."""
STORE_SPP = 256
"""bench_bitmap_design.py's stores: their render noise is 1-2x the sensor's."""


def search(root: Path, folders, cells: int, starts: int, iterations: int,
           still_weight: float = 0.0, aggregate: str = "mean", focus_mm=(),
           space: str = "bitmap") -> dict:  # fmt: skip
    """One bitmap search on ``folders``: its best candidate on the unread passes written as a
    design file, its gain there over the store's design, what the choice kept, seconds."""
    t0 = time.perf_counter()
    p = BitmapProblem(tuple(folders), bbd.SENSOR, bbd.LEVEL, cells, "fixed", starts,
                      iterations, noise_draws=2,
                      objective="moving+still" if still_weight else "moving",
                      still_weight=still_weight or None, aggregate=aggregate,
                      focus_mm=tuple(focus_mm), space=space)  # fmt: skip
    opened = check_bitmap_problem(p)
    prepared = prepare_bitmap(p, opened)
    f = chosen_design(p, prepared, opened, found_over_focus(p, opened, prepared))
    model = SensorModel.from_preset(bbd.SENSOR)
    noise = [store_noise(t, model, bbd.LEVEL, bbd.SENSOR)[0] for t in prepared["templates"]]
    scores = f["choice"]["scores"]
    best = max((k for k in scores if k != PROTOTYPE), key=lambda k: scores[k]["value_db"])
    tags = ("_still" if still_weight else "") + ("_worst" if aggregate == "worst" else "")
    tags += "_focus" if focus_mm else ""
    path = root / f"{space}_n{len(folders)}_g{cells}{tags}.toml"
    write_design(path, f["candidates"][best], True)
    out = {"path": path, "best": best, "chosen": f["choice"]["chosen"],
           "train_gain_db": scores[best]["value_db"] - scores[PROTOTYPE]["value_db"],
           "seconds": time.perf_counter() - t0, "noise": (min(noise), max(noise))}  # fmt: skip
    del prepared, f
    gc.collect()  # one search's bases in memory at a time
    return out


def held_rows(found: dict, spp: int, rseeds: int, seeds, target=None) -> list[dict]:
    """Report rows of the prototype, Levin's camera and each found design on every held-out
    scene (``seeds``), fresh direct renders (``rseeds`` render seeds), 2 new sensor draws; with
    a ``target`` (a :class:`SensorTarget`), each render runs ``spp`` x 2 pilot passes and then
    as many as its Monte Carlo sigma needs to meet it, so that no design is compared in more
    render noise than another (a bitmap's open cells are scattered over the lens, where the
    plugin spreads its samples: at a fixed spp it keeps 2-3x the prototype's render noise)."""
    rows = []
    for seed in seeds:
        for j in range(rseeds):
            rs = 5000 + 10 * seed + j
            base = bbd.spec(seed, spp, rs)
            specs = [("prototype", base), ("levin (650 mm)", replace(base, mode="levin"))]
            specs += [(name, design_spec(base, v["path"])) for name, v in found.items()]
            ref = None
            for name, s in specs:
                cap = render_capture(s, progress=False, truth=True, target=target)
                ref = cap if ref is None else ref
                rows.append(design_row(name, f"{seed}/{rs}", cap, ref, bbd.SENSOR, bbd.LEVEL,
                                       (9000 + rs, 9500 + rs), unit=str(seed)))  # fmt: skip
        print(f"held-out seed {seed}: done", flush=True)
    return rows


def table(found: dict, held: list[dict]) -> list[dict]:
    moving, still, whole = paired(held), paired(held, "psnr_static_db"), paired(held, "psnr_db")
    ci = lambda d: "-" if d is None else f"{d[0]:+.2f} [{d[1]:+.2f}, {d[2]:+.2f}] n={d[3]}"  # noqa: E731
    rows = []
    for r in summary(held):
        f = found.get(r["design"], {})
        gain, noise = f.get("train_gain_db"), r.get("render_noise_ratio")
        rows.append({
            "design": r["design"],
            "train gain, unread passes (dB)": "n/a" if gain is None else f"{gain:+.2f}",
            "choice kept": f.get("chosen", "n/a"),
            "render noise / sensor": "n/a" if noise is None else f"{noise:.2f}",
            "held moving (dB)": f"{r['psnr_moving_db']:.2f}",
            "moving vs prototype (95 %)": ci(moving.get(r["design"])),
            "still vs prototype (95 %)": ci(still.get(r["design"])),
            "whole vs prototype (95 %)": ci(whole.get(r["design"])),
            "search s": f"{f['seconds']:.0f}" if "seconds" in f else "n/a",
        })  # fmt: skip
    return rows


@dataclass(frozen=True)
class Setup:
    """One run's sizes (main() reads them from the flags, or the quick smoke sizes)."""

    counts: tuple
    grids: tuple
    starts: int
    iters: int
    store_spp: int
    spp: int
    held: tuple
    still_weight: float = 0.0
    noise_ratio: float | None = None
    aggregate: str = "mean"
    focus_mm: tuple = ()
    space: str = "bitmap"

    @property
    def objective(self) -> str:
        what = (
            "moving objects' PSNR"
            if not self.still_weight
            else f"(moving + {self.still_weight:g} still) / {1 + self.still_weight:g} in dB"
        )
        if self.aggregate == "worst":
            return (f"{what}, pooled over the stores as the soft minimum (tau "
                    f"{WORST_SOFTNESS_DB:g} dB) of the gains over the prototype")  # fmt: skip
        return f"{what}, mean over the stores"


def _focus_words(u: Setup) -> str:
    return "the store's and " + ", ".join(f"{f:g}" for f in u.focus_mm) + " mm"


def _found(root: Path, u: Setup, designs_from: list | None, only: list | None):
    """The searches' results (name to search()'s dict) and the stores' seconds; read from
    ``designs_from`` (runs' scenes.json files; a name in several gets its run's folder) instead
    where given, keeping the names containing one of ``only``."""
    if designs_from:
        out = {}
        for f in designs_from:
            for k, v in json.loads(Path(f).read_text())["found"].items():
                name = f"{k} [{Path(f).parent.name}]" if len(designs_from) > 1 else k
                if not only or any(o in name for o in only):
                    out[name] = {**v, "path": Path(v["path"])}
        return out, None
    t0 = time.perf_counter()
    folders = bbd.stores(root, u.store_spp, TRAIN_SEEDS[: max(u.counts)])
    t_store = time.perf_counter() - t0
    found = {}
    for n in u.counts:
        for g in u.grids:
            name = f"{u.space} {g}x{g}, {n} scenes" + (", moving+still" if u.still_weight else "")
            name += ", worst case" if u.aggregate == "worst" else ""
            name += f", focus searched ({_focus_words(u)})" if u.focus_mm else ""
            found[name] = search(root, folders[:n], g, u.starts, u.iters, u.still_weight,
                                 u.aggregate, u.focus_mm, u.space)  # fmt: skip
            print(f"{name}: {found[name]}", flush=True)
    return found, t_store


def _ranges(seeds) -> str:
    """Seeds as runs: (10, 11, 12, 42, 43) -> '10-12, 42-43'."""
    runs = [[seeds[0], seeds[0]]]
    for x in seeds[1:]:
        if x == runs[-1][1] + 1:
            runs[-1][1] = x
        else:
            runs.append([x, x])
    return ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs)


def _renders(u: Setup) -> str:
    if u.noise_ratio is None:
        return f"spp {u.spp} x 2 passes (render noise: each design's own, in the table)"
    return (
        f"to a Monte Carlo sigma of at most {u.noise_ratio:g}x the sensor's noise "
        f"(pilot spp {u.spp} x 2 passes; render noise reached: in the table)"
    )


def baselines(root: Path) -> dict:
    """bench_bitmap_design.py's best centres design and Fourier-model design, where its run
    left them in ``root``: the issue's other comparisons."""
    out = {}
    for name, folder in (("best centres design", "centres"), ("Fourier-model design", "fourier")):
        if (root / folder / "design.toml").exists():
            out[name] = {"path": root / folder / "design.toml"}
    return out


def _train_text(found: dict, u: Setup, t_store, sources) -> str:
    """What the checked designs were searched on: this run's searches, or earlier runs'."""
    if sources:
        return (f"designs read from {', '.join(sources)} (their searches: those runs' RESULTS "
                "sections; train gain and choice as they recorded them)")  # fmt: skip
    noise = [v["noise"] for v in found.values() if "noise" in v]
    noise = f"{min(n[0] for n in noise):.2f}-{max(n[1] for n in noise):.2f}x" if noise else "n/a"
    return (f"train: the first N of family seeds {TRAIN_SEEDS[0]}-9, 20-41 (N in {u.counts}), "
            f"128x64 windows at each scene's largest occlusion, grey stores spp {u.store_spp} x "
            f"{bbd.STORE_PASSES} passes ({t_store:.0f} s; the searched passes' render noise "
            f"{noise} the sensor's); {u.space} search on the G x G cells (G in {u.grids}), fixed "
            f"light, {u.objective}, {u.starts} starts x {u.iters} Adam steps, reading 2 "
            "passes; its best candidate on the other 2 is checked (train gain: its margin over "
            "the store's design there; choice kept: what pacam optimize would write)")  # fmt: skip


def _notes(found: dict, u: Setup, t_store, sources=None) -> str:
    h = u.held
    return (f"{_train_text(found, u, t_store, sources)}; "
            f"{len(h)} checked scenes (family seeds {_ranges(h)}): fresh direct renders "
            f"{_renders(u)}, {RENDER_SEEDS} render seed(s) per scene "
            "(averaged before the intervals, which are over scenes), 2 new sensor draws, "
            f"{bbd.SENSOR} at {bbd.LEVEL:g} photons/px/ms, Wiener; every camera focused for "
            f"{bbd.MIDDLE_DEPTH_MM:g} mm")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a smoke run")
    ap.add_argument(
        "--root",
        default="/tmp/bench_bitmap_design",
        help="stores are reused from here (bench_bitmap_design.py's root)",
    )
    ap.add_argument("--store-spp", type=int, default=STORE_SPP, help="samples per store pass")
    ap.add_argument("--counts", type=int, nargs="+", default=COUNTS, help="training scenes")
    ap.add_argument("--grids", type=int, nargs="+", default=GRIDS, help="cells across")
    ap.add_argument(
        "--still-weight",
        type=float,
        default=0.0,
        help="search (moving + W still) / (1 + W) in dB, not moving alone",
    )
    ap.add_argument("--check-seeds", type=int, nargs="+",
                    help="family seeds to check on instead of the held-out ones (the training "
                    "seeds: what fresh renders of the scenes it was fitted on give)")  # fmt: skip
    ap.add_argument(
        "--designs-from",
        nargs="+",
        help="earlier runs' scenes.json: check their designs again (no search)",
    )
    ap.add_argument(
        "--only",
        nargs="+",
        help="with --designs-from: the designs whose names contain one of these",
    )
    ap.add_argument(
        "--noise-ratio",
        type=float,
        help="render every checked capture to at most this times the sensor's "
        "noise (pilot: the spp x 2 passes), not to a fixed spp",
    )
    ap.add_argument(
        "--baselines",
        action="store_true",
        help="check the root's best centres and Fourier-model designs too",
    )
    ap.add_argument(
        "--space",
        default="bitmap",
        help=f"what the searches move: {' or '.join(CELL_SPACES)} (pacam optimize --space)",
    )
    ap.add_argument(
        "--focus",
        type=float,
        nargs="+",
        metavar="MM",
        help="further focus distances each search tries (pacam optimize --focus)",
    )
    ap.add_argument(
        "--aggregate",
        default="mean",
        help=f"how a search pools the stores: {' or '.join(AGGREGATES)} (pacam optimize's)",
    )
    a = ap.parse_args()  # fmt: skip
    warnings.simplefilter("ignore")  # the family's off-depth notes, once per capture
    u = (Setup((2, 3), (8,), 2, 3, 16, 16, HELD_SEEDS[:12], a.still_weight) if a.quick
         else Setup(tuple(a.counts), tuple(a.grids), STARTS, ITERATIONS, a.store_spp, 64,
                    HELD_SEEDS, a.still_weight))  # fmt: skip
    if a.check_seeds:
        u = replace(u, held=tuple(a.check_seeds))
    if a.aggregate not in AGGREGATES:
        ap.error(f"--aggregate must be one of {', '.join(AGGREGATES)}, got {a.aggregate!r}")
    if a.space not in CELL_SPACES:
        ap.error(f"--space must be one of {', '.join(CELL_SPACES)}, got {a.space!r}")
    if any(not 0 < f < float("inf") for f in a.focus or ()):
        ap.error(f"--focus: focus distances finite and > 0 (mm), got {a.focus}")
    u = replace(u, aggregate=a.aggregate, focus_mm=tuple(a.focus or ()), space=a.space)
    if a.only and not a.designs_from:
        ap.error("--only picks among --designs-from's designs; give --designs-from too")
    if a.noise_ratio is not None:
        if not 0 < a.noise_ratio < float("inf"):
            ap.error(
                f"--noise-ratio must be finite and > 0 (a share of the sensor's noise), "
                f"got {a.noise_ratio}"
            )
        u = replace(u, noise_ratio=a.noise_ratio)
        target = SensorTarget(a.noise_ratio, ((bbd.SENSOR, bbd.LEVEL),))
    root = Path(a.root)
    root.mkdir(parents=True, exist_ok=True)
    found, t_store = _found(root, u, a.designs_from, a.only)
    checked = {**(baselines(root) if a.baselines else {}), **found}
    held = held_rows(checked, u.spp, RENDER_SEEDS, u.held,
                     None if u.noise_ratio is None else target)  # fmt: skip
    tag = "" if u.noise_ratio is None else f"_noise{u.noise_ratio:g}"
    tag += "_worst" if u.aggregate == "worst" else ""
    tag += "_focus" if u.focus_mm else ""
    tag += "" if u.space == "bitmap" else f"_{u.space}"
    out = root / (f"scenes_checked{tag}.json" if a.designs_from else f"scenes{tag}.json")
    out.write_text(json.dumps({"found": {k: {**v, "path": str(v["path"])}
                                         for k, v in found.items()}, "held": held},
                              indent=1))  # fmt: skip
    rows, notes = table(found, held), _notes(found, u, t_store, a.designs_from)
    if a.quick:
        print(rows, notes + " (QUICK smoke sizes)")
        return
    extra = "" if u.store_spp == STORE_SPP else f", stores of {u.store_spp} spp"
    extra += f", still weight {u.still_weight:g}" if u.still_weight else ""
    extra += ", worst-case aggregate" if u.aggregate == "worst" else ""
    extra += f", focus searched ({_focus_words(u)})" if u.focus_mm else ""
    extra += "" if u.space == "bitmap" else f", --space {u.space}"
    extra += f", checked on family seeds {u.held[0]}-{u.held[-1]}" if a.check_seeds else ""
    extra += "" if u.noise_ratio is None else f", renders to {u.noise_ratio:g}x the sensor's noise"
    extra += ", with the root's centres and Fourier-model designs" if a.baselines else ""
    record(f"Whole-aperture designs: held-out gain against the number of training scenes{extra}",
           rows, notes)  # fmt: skip


if __name__ == "__main__":
    main()
