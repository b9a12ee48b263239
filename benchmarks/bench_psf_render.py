"""Rendered-PSF error against samples and run time: ``ptracer`` vs ``path`` (issue 6).

The scene: the prototype at 500 mm (r = 2 px, a_i = -0.0398 px/ms^2), a point moving at
0.5 px/ms, the coded (16-pattern) schedule; the 47x47 PSF is rendered per pattern window
with :mod:`pacam_render.psf_render.render` on a kernel-sized film. Both integrators see the
same scene: a disc source of psf_scene's default radius, 0.25 px (a camera ray must hit it, so
the 0.02 px source of the validation would starve ``path``), ``max_depth`` 2, box filter. The
reference is a high-spp ``ptracer`` render of that scene; errors are L1 distances of normalised
kernels (0 = equal, 2 = disjoint), averaged over the timed repeats (different seeds).

spp is Mitsuba's: particles (ptracer) or camera rays (path) per film pixel, per window, so the
two columns of samples are comparable. Slopes are least-squares fits of log L1 against log spp
and log seconds over the points whose error is at least 3x the reference's own noise.
Writes benchmarks/figures/psf_render_error.png.

    python benchmarks/bench_psf_render.py [--full]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from common import median_spread, record, timeit
from matplotlib.ticker import NullFormatter

from pacam_render.model.camera import prototype
from pacam_render.psf_render import render as prd
from pacam_render.psf_render.spec import PSFSpec
from pacam_render.restore import metrics

DEPTH_MM, SPEED = 500.0, 0.5
SOURCE_PX = 0.25
FIG = Path(__file__).with_name("figures") / "psf_render_error.png"


def slope(x, y, ok) -> float:
    x, y, ok = np.asarray(x, float), np.asarray(y, float), np.asarray(ok, bool)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="more spp values, repeats, reference")
    args = ap.parse_args()
    repeat = 5 if args.full else 3
    sweeps = {
        "ptracer": [1, 2, 4, 8, 16, 32, 64, 128, 256] + ([512, 1024] if args.full else []),
        "path": [16, 64, 256, 1024] + ([4096, 16384] if args.full else []),
    }
    ref_spp = 16384 if args.full else 4096
    cam = prototype().with_(object_depth_mm=DEPTH_MM)
    rnd = prd.PSFRenderer(source_radius_px=SOURCE_PX)
    kw = dict(threads=None)  # all Dr.Jit threads: the fastest set-up for both integrators

    t0 = time.perf_counter()
    ref = rnd.render(cam, PSFSpec("coded", SPEED, spp=ref_spp, seed=10**6, **kw))
    ref2 = rnd.render(cam, PSFSpec("coded", SPEED, spp=ref_spp, seed=10**6 + 1, **kw))
    ref_kernel = 0.5 * (ref.kernel + ref2.kernel)
    ref_noise = metrics.rel_l1(ref.kernel, ref2.kernel) / 2  # L1 of the mean against the truth
    ref_s = time.perf_counter() - t0
    shape = ref.kernel.shape

    rows, curves = [], {}
    for integ, spps in sweeps.items():
        pts = []
        for spp in spps:
            errs, seeds = [], iter(range(1000))

            def run(integ=integ, spp=spp, errs=errs, seeds=seeds):
                spec = PSFSpec(
                    "coded", SPEED, spp=spp, seed=next(seeds), integrator=integ, size=shape, **kw
                )
                r = rnd.render(cam, spec)
                errs.append(metrics.rel_l1(r.kernel, ref_kernel))
                return r

            times = timeit(run, repeat=repeat, warmup=1)
            med, spread = median_spread(times)
            err = float(np.mean(errs[1:]))  # the timed repeats
            samples = spp * shape[0] * shape[1] * 16
            pts.append((spp, med, err))
            rows.append(
                {
                    "integrator": integ,
                    "spp/window": spp,
                    "samples": samples,
                    "median s": med,
                    "± s": spread,
                    "L1 vs ref": err,
                    "L1 spread": float(np.std(errs[1:])),
                    "Msamples/s": samples / med / 1e6,
                }
            )
        curves[integ] = pts
    slopes = {}
    for integ, pts in curves.items():
        spp, sec, err = (np.array(v) for v in zip(*pts))
        ok = err > 3 * ref_noise
        busy = ok & (sec > 2 * sec.min())  # past the fixed cost of the 16 render calls
        slopes[integ] = (slope(spp, err, ok), slope(sec, err, ok), slope(sec, err, busy))
    for r in rows:
        r["slope vs spp"], r["slope vs s"], r["slope vs s (t > 2 t_min)"] = slopes[r["integrator"]]

    notes = (
        f"prototype at {DEPTH_MM:g} mm, coded, s = {SPEED} px/ms, {shape[0]}x{shape[1]} kernel, "
        f"16 pattern windows, source {SOURCE_PX} px; reference: 2 x ptracer {ref_spp} spp "
        f"({ref_s:.0f} s), its own L1 noise {ref_noise:.2e}; {repeat} timed repeats after 1 "
        "warm-up (each a new seed); all Dr.Jit threads; slopes: log-log least squares over "
        "points with L1 > 3x the reference noise; at small budgets the fixed cost of the 16 "
        "render calls (~3 ms each) dominates, so the last column fits only points that take more "
        "than 2x the fastest"
    )
    record("Rendered PSF: L1 error vs spp and run time, ptracer vs path (issue 6)", rows, notes)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.3))
    for integ, pts in curves.items():
        spp, sec, err = (np.array(v) for v in zip(*pts))
        s_spp, s_sec, s_busy = slopes[integ]
        ax[0].loglog(spp, err, "o-", label=f"{integ}: slope {s_spp:.2f}")
        ax[1].loglog(sec, err, "o-", label=f"{integ}: slope {s_sec:.2f} (long runs {s_busy:.2f})")
    ax[1].xaxis.set_minor_formatter(NullFormatter())
    for a in ax:
        a.axhline(ref_noise, color="k", ls=":", lw=0.8, label="reference noise")
        a.set_ylabel("L1 vs reference")
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=8)
    ax[0].set_xlabel("spp per window (samples per film pixel)")
    ax[1].set_xlabel("render time, s (16 windows)")
    ax[0].set_title("error vs samples")
    ax[1].set_title("error vs run time")
    fig.suptitle(
        f"rendered PSF, prototype {DEPTH_MM:g} mm, s = {SPEED} px/ms, {SOURCE_PX} px source",
        fontsize=10,
    )
    fig.tight_layout()
    FIG.parent.mkdir(exist_ok=True)
    fig.savefig(FIG, dpi=110)
    print(f"wrote {FIG}")
    for integ, (a, b, c) in slopes.items():
        print(f"{integ}: slope vs spp {a:.3f}, vs seconds {b:.3f} (long runs {c:.3f})")


if __name__ == "__main__":
    main()
