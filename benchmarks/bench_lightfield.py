"""Light-field stores against direct renders: cost per design, and paired design comparisons.

On a window of the moving train at the prototype's pixel scale (both trains, occlusion), with
covering designs of one F-number (the speed study's axis: they share the parabola and differ
in focus):

1. **Cost to one Monte Carlo sigma.** Each way's error per second is measured on the output
   itself. Direct renders of a subset of the designs give the target sigma (their mean) and
   the cost per design to reach it (sigma^2 t). A pilot store with as many samples and time
   steps as a direct render (4x its spp: a direct render of N spp takes 4 spp in each of its
   16 pattern windows per pass) gives the samples the store needs for its worst design; the
   store is rendered with them, and each design's synthesis from it is timed. So the
   comparison is N direct renders against one store plus N syntheses, each measured.
2. **Paired comparisons.** Over seeds, the sd of PSNR(A) - PSNR(B) (each capture against its
   ``sharp`` layer, white = 1): two designs synthesised from one store per seed, against two
   independent direct renders per seed (the store with as many samples and time steps).

3. **A schedule found by rendering** (``--only optimize``). One store per window (each
   train's trailing end, the football's), ``pacam optimize --lightfield`` on them, and
   ``pacam optimize``'s Fourier objective for the same speeds and depths; the two designs and
   the parabola they start from are rendered directly with new seeds and scored alike (the
   sensor, Wiener told the sensor's and render's noise, the moving objects against sharp).

    python benchmarks/bench_lightfield.py [--quick] [--only cost|paired|synthesis|alpha|optimize]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from common import record

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.model.camera import preset
from pacam_render.model.design_file import write_design


def _psnr(image, sharp, lf) -> float:
    mse = float(np.mean((image / lf - sharp) ** 2))
    return 10 * np.log10(1.0 / mse)


def _timed(fn, *args, **kw):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def _sigma(cap) -> float:
    return float(np.sqrt(np.mean(cap.mc_sigma**2)))


def cost_table(window: dict, n_designs: tuple, spp: int, direct_subset: int, root: Path):
    covers = np.linspace(0.6, 1.6, max(n_designs))
    specs = [
        CaptureSpec.geometric(**window, mode="coded", cover_px_per_ms=float(c), spp=spp, passes=4)
        for c in covers
    ]
    picks = np.linspace(0, len(specs) - 1, direct_subset).round().astype(int)
    direct = [
        _timed(render_capture, replace(specs[i], seed=7), progress=False, truth=False)
        for i in picks
    ]
    sig_d = [_sigma(c) for c, _ in direct]
    target = float(np.mean(sig_d))  # bring every design to the direct renders' mean sigma
    per_direct = float(np.mean([t * (s / target) ** 2 for (_, t), s in zip(direct, sig_d)]))
    # a pilot store of as many samples and steps as a direct render (4 spp in each of its 16
    # pattern windows per pass) says how many the store needs; the store is then rendered
    # with that many, and every synthesis from it timed: nothing is scaled
    designs = (specs[0], specs[-1])
    pilot = render_lightfield(StoreSpec(replace(specs[0], seed=1, spp=4 * spp), designs=designs),
                              root / "pilot", progress=False, truth=False)  # fmt: skip
    worst = max(_sigma(synthesize(pilot, s, progress=False)) for s in specs[:: len(specs) // 8])
    store_spp = 16 * int(np.ceil(4 * spp * (worst / target) ** 2 / 16))
    spec = StoreSpec(replace(specs[0], seed=2, spp=store_spp), designs=designs)
    store, t_store = _timed(render_lightfield, spec, root / "cost", progress=False, truth=False)
    syn = [_timed(synthesize, store, s, progress=False) for s in specs]
    rows = []
    for n in n_designs:
        sig = [_sigma(c) for c, _ in syn[:n]]
        t_syn = float(np.mean([t for _, t in syn[:n]]))
        t_lf = t_store + n * t_syn
        rows.append(
            {
                "designs": n,
                "direct s (to sigma)": n * per_direct,
                "store + syntheses s": t_lf,
                "ratio": t_lf / (n * per_direct),
                "store spp/pass": store_spp,
                "store s": t_store,
                "synthesis s/design": t_syn,
                "worst synth sigma / target": max(sig) / target,
            }
        )
    return rows, target


def _dpsnr(ca, cb) -> float:
    """PSNR(A) - PSNR(B), each capture against its own sharp layer."""
    a = _psnr(ca.image, ca.extra_layers["sharp"], ca.record.light_factor)
    return a - _psnr(cb.image, cb.extra_layers["sharp"], cb.record.light_factor)


def paired_table(window: dict, seeds: int, spp: int, root: Path):
    proto = preset("prototype")
    wider = root / "wider.toml"
    write_design(wider, proto.with_(R_mm=1.1 * proto.R_mm, name="wider"), force=True)
    pairs = {
        "prototype vs 1.1 R (same focus)": {"design": str(wider)},
        "prototype vs cover 1.4 (refocused)": {"cover_px_per_ms": 1.4},
    }
    rows = []
    for name, other in pairs.items():
        a = CaptureSpec.geometric(**window, mode="coded", spp=spp, passes=4)
        b = replace(a, **other)
        d_store, d_direct, sig_s, sig_d = [], [], [], []
        for seed in range(seeds):
            folder = root / f"paired{seed}"
            shutil.rmtree(folder, ignore_errors=True)
            spec = StoreSpec(replace(a, seed=100 + seed, spp=4 * spp), designs=(a, b))
            store, _ = _timed(render_lightfield, spec, folder, progress=False)
            ca, _ = _timed(synthesize, store, a, progress=False)
            cb, _ = _timed(synthesize, store, b, progress=False)
            ra, _ = _timed(render_capture, replace(a, seed=200 + 2 * seed), progress=False)
            rb, _ = _timed(render_capture, replace(b, seed=201 + 2 * seed), progress=False)
            d_store.append(_dpsnr(ca, cb))
            d_direct.append(_dpsnr(ra, rb))
            sig_s.append(_sigma(ca))
            sig_d.append(_sigma(ra))
        sd_s, sd_d = float(np.std(d_store, ddof=1)), float(np.std(d_direct, ddof=1))
        rows.append(
            {
                "pair": name,
                "seeds": seeds,
                "mean dPSNR store (dB)": float(np.mean(d_store)),
                "sd store (dB)": sd_s,
                "mean dPSNR direct (dB)": float(np.mean(d_direct)),
                "sd direct (dB)": sd_d,
                "sd ratio": sd_s / sd_d,
                "MC sigma store / direct": float(np.mean(sig_s) / np.mean(sig_d)),
            }
        )
    return rows


def synthesis_table(spp: int, root: Path) -> list[dict]:
    """Seconds per synthesis of a 400x160 window (the issue's size), against its samples."""
    window = {"scene": "train", "width": 1280, "height": 960, "crop": (440, 400, 400, 160)}
    base = CaptureSpec.geometric(**window, spp=spp, passes=4, seed=3)
    store, t_store = _timed(render_lightfield, StoreSpec(base), root / "big", progress=False,
                            truth=False)  # fmt: skip
    rows = []
    for name, extra in (("prototype", {}), ("cover 1.4", {"cover_px_per_ms": 1.4}),
                        ("normal", {"mode": "normal"})):  # fmt: skip
        spec = replace(base, **extra)
        synthesize(store, spec, progress=False)  # the shards read once, the kernels once
        cap, t = _timed(synthesize, store, spec, progress=False)
        used = cap.record.extra["lightfield"]["samples_used"]
        row = {"design": name, "store spp/pass": spp, "store s": t_store, "synthesis s": t}
        rows.append({**row, "samples used (M)": used / 1e6, "MC sigma": _sigma(cap)})
    return rows


def alpha_table(window: dict, spp: int, root: Path) -> list[dict]:
    """The proposal's uniform share against the MC sigma of designs in it and not in it."""
    proto = preset("prototype")
    write_design(root / "wider13.toml", proto.with_(R_mm=1.3 * proto.R_mm, name="w"), force=True)
    base = CaptureSpec.geometric(**window, mode="coded", spp=spp, passes=4, seed=1)
    listed = (base, replace(base, cover_px_per_ms=1.4))
    designs = {
        "prototype (listed)": base,
        "cover 1.4 (listed)": listed[1],
        "normal (not listed)": replace(base, mode="normal"),
        "1.3 R (not listed)": replace(base, design=str(root / "wider13.toml")),
    }
    rows = []
    for alpha in (0.05, 0.1, 0.2, 0.4, 1.0):
        spec = StoreSpec(base, designs=listed, alpha=alpha, margin_px=8)
        store = render_lightfield(spec, root / f"alpha{alpha}", progress=False, truth=False)
        sig = {k: _sigma(synthesize(store, s, progress=False)) for k, s in designs.items()}
        rows.append({"alpha": alpha, **{f"sigma {k}": v for k, v in sig.items()}})
    return rows


OPT_WINDOWS = {
    "far train (1.0 px/ms)": ("train", (944, 300, 160, 96)),
    "near train (1.4 px/ms)": ("train", (1032, 590, 160, 96)),
    "ball (1.0 px/ms, 1000 mm)": ("soccer", (720, 420, 160, 96)),
}
"""The windows of the optimiser's search and check: each train's trailing end (its moving edge
occludes the backdrop) and the football's."""
OPT_SENSOR = "grasshopper-icx285-mono"


def optimize_table(root: Path, quick: bool) -> tuple[list[dict], str]:
    """The rendered-objective design against the Fourier-objective design and the parabola
    the stores were rendered for (cover 1.4), on fresh direct renders of the three windows
    (new render seeds, new sensor draws). The rendered search takes one store per window (the
    store's seed 7); the Fourier search the same speeds and the windows' depths, 495-1000 mm."""
    from pacam_render.optimize.rendered import CaptureScorer
    from pacam_render.optimize.rendered_run import RenderedProblem, run_rendered_optimize
    from pacam_render.optimize.run import run_optimize
    from pacam_render.optimize.search import Problem

    spp, passes, seeds = (32, 2, 3) if quick else (64, 4, 5)
    base = dict(width=1280, height=960, grey=True, cover_px_per_ms=1.4, mode="coded",
                max_step_px=0.5)  # fmt: skip
    stores = []
    t0 = time.perf_counter()
    for scene, crop in OPT_WINDOWS.values():
        spec = CaptureSpec.geometric(scene=scene, crop=crop, spp=spp, passes=passes, seed=7, **base)
        folder = root / f"opt_store_{len(stores)}"
        _timed(render_lightfield, StoreSpec(spec, alpha=1.0), folder, progress=False)
        stores.append(str(folder))
    store_s = time.perf_counter() - t0
    problem = RenderedProblem(tuple(stores), sensor=OPT_SENSOR, sweeps=1 if quick else 2,
                              check_seeds=0)  # fmt: skip
    for sub in ("rendered", "fourier"):
        (root / sub).mkdir()
    doc, search_s = _timed(run_rendered_optimize, problem, root / "rendered", False, False)
    fourier = Problem(1.4, (495.0, 1000.0), 16, OPT_SENSOR, 300.0)  # the trains' and ball's
    _, fourier_s = _timed(run_optimize, fourier, root / "fourier", quick=quick, seed=0,
                          force=False, progress=False)  # fmt: skip
    designs = {
        "parabola (cover 1.4)": {},
        "Fourier objective": {"design": str(root / "fourier" / "design.toml")},
        "rendered objective": {"design": str(root / "rendered" / "design.toml")},
    }
    psnr = {d: np.zeros((len(OPT_WINDOWS), seeds)) for d in designs}
    for i, (scene, crop) in enumerate(OPT_WINDOWS.values()):
        for j in range(seeds):
            for d, fields in designs.items():
                kw = {**base, **({"cover_px_per_ms": None, **fields} if fields else {})}
                spec = CaptureSpec.geometric(
                    scene=scene, crop=crop, spp=spp * 4, seed=100 + j, **kw
                )
                cap, _ = _timed(render_capture, spec, progress=False, truth=True)
                scorer = CaptureScorer(cap, OPT_SENSOR, 300.0, (500 + j,))
                psnr[d][i, j] = scorer.psnr_db(cap)
    rows = []
    worst = {d: v.min(axis=0) for d, v in psnr.items()}  # per seed, over the windows
    for d in designs:
        diff = worst[d] - worst["Fourier objective"]
        half = _t95(diff)
        ci = "" if half is None else f"[{diff.mean() - half:+.2f}, {diff.mean() + half:+.2f}]"
        per = {w: float(psnr[d][i].mean()) for i, w in enumerate(OPT_WINDOWS)}
        rows.append({"design": d, **per, "worst case (dB)": float(worst[d].mean()),
                     "vs Fourier (dB)": float(diff.mean()), "95 % interval": ci})  # fmt: skip
    notes = (
        f"stores: one per window, {spp} spp x {passes} passes, uniform share 1, {store_s:.0f} s; "
        f"rendered search {search_s:.0f} s ({doc['evaluations']} evaluations, "
        f"{doc['start_worst_db']:.2f} -> {doc['found_worst_db']:.2f} dB on the stores); "
        f"Fourier search {fourier_s:.0f} s; fresh renders {spp * 4} spp, seeds 100-{99 + seeds}, "
        f"{OPT_SENSOR} at 300 photons/px/ms, Wiener told the sensor's and render's noise"
    )
    return rows, notes


def _t95(d: np.ndarray) -> float | None:
    from scipy import stats

    if len(d) < 2:
        return None
    return float(stats.t.ppf(0.975, len(d) - 1) * np.std(d, ddof=1) / np.sqrt(len(d)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a smaller window and fewer seeds")
    ap.add_argument("--only", choices=("cost", "paired", "synthesis", "alpha", "optimize"),
                    help="one table")  # fmt: skip
    args = ap.parse_args()
    crop = (456, 410, 48, 32) if args.quick else (440, 400, 96, 64)
    window = {"scene": "train", "width": 1280, "height": 960, "crop": crop}
    root = Path(tempfile.mkdtemp(prefix="bench_lightfield."))
    wanted = (
        {"cost", "paired", "synthesis", "alpha", "optimize"} if args.only is None else {args.only}
    )
    try:
        if "cost" in wanted:
            rows, target = cost_table(window, (1, 4, 16, 64), 16, 4, root)
            record(
                "Light-field store: wall time to one Monte Carlo sigma, N covering designs",
                rows,
                f"train window {crop} at 1280x960, moving; covers 0.6-1.6 px/ms (F9.85); "
                f"target sigma {target:.3g} (the direct renders' mean); direct cost per design "
                "measured on 4 of the designs",
            )
        if "paired" in wanted:
            record(
                "Light-field store: sd over seeds of PSNR(A) - PSNR(B)",
                paired_table(window, 3 if args.quick else 5, 16, root),
                f"train window {crop}, each capture's PSNR against its sharp layer (no "
                "deconvolution); one store per seed against two direct renders per seed",
            )
        if "synthesis" in wanted:
            record(
                "Light-field store: synthesis time of a 400x160 window",
                synthesis_table(16 if args.quick else 64, root),
                "train window (440, 400, 400, 160) at 1280x960, moving; the second synthesis "
                "of each design timed (the store's shards and the optics budget's kernels are "
                "kept from the first)",
            )
        if "alpha" in wanted:
            record(
                "Light-field store: the proposal's uniform share alpha, MC sigma per design",
                alpha_table(window, 64, root),
                f"train window {crop}, 64 spp x 4 passes, stores of equal cost; the proposal "
                "lists the prototype and cover 1.4",
            )
        if "optimize" in wanted:
            rows, notes = optimize_table(root, args.quick)
            record(
                "Light-field store: the rendered-objective schedule on fresh renders",
                rows,
                "worst case over the three windows' moving objects, mean over fresh seeds; "
                + notes,
            )
    finally:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
