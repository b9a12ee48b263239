"""The render's own error against its cost (issue 25): samplers, time steps, bounces.

1. Samplers: Mitsuba's sample generators on a coded capture of the train at the prototype's
   full pixel scale (a 200x120 window at (200, 560): the near train over the backdrop, the
   capture's own step plan), at equal spp. The Monte Carlo sigma is measured from two seeds,
   the time is the capture's ``render_seconds`` (no ground truth); efficiency 1/(sigma^2 t)
   against ``independent``, side by side in one run. The sigma each capture records beside it,
   and each sampler's mean against ``independent``'s (bias, in units of their joint sigma).
2. Time steps: a moving point (PSF scene, normal exposure: a 58 px streak) and the train window,
   with stratified random times (each step's geometry and rays at one uniform time in it,
   the default) and the midpoint rule (the earlier captures), at several step sizes. The error
   is measured against a fine-step reference of many samples (its own noise taken out), and
   split into the recorded Monte Carlo sigma and what it does not cover (the midpoint's
   bias). Efficiency 1/(error^2 t).
3. Bounces: how much light the paths past the first bounce add to each built-in scene
   (``path`` max_depth 2, 3, 4 and 8, the reference camera, full pixel scale), in white units,
   against the noise target of a study (0.2 x the ICX285's noise at 300 and 10^4
   photons/px/ms), and what each depth costs.
4. Error against seconds for a capture of the train window: the Monte Carlo sigma of the
   default and of ``independent`` at 1024 to 4096 spp (1024 is the default's smallest capture
   here: 2 passes of 4 spp in each of 128 steps), and the midpoint rule's total error,
   plotted to ``benchmarks/figures/render_error_vs_seconds.png`` (and docs/render_error.png).

5. The steps' times as one stream: one uniform draw per pass shared by every step (a randomly
   shifted grid of times, still unbiased) against an independent draw per step.

6. The noise-target planner: a step's fixed cost against its samples (the constant
   ``progress.STEP_OVERHEAD_PX_SAMPLES`` of the pass-cost model), and a capture of the train
   window rendered to a target with the re-plan (a + b / spp, the cheapest pass size) against
   one pass size added a pass at a time (the earlier planner), for a short exposure (where the
   poses' floor dominates) and a coded one.

    python benchmarks/bench_render_error.py [--full] [--quick] [--part 1 2 3 4 5 6]
"""

from __future__ import annotations

import argparse
import contextlib
import shutil
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from common import record
from matplotlib.ticker import ScalarFormatter

from pacam_render.exposure import integrate, progress
from pacam_render.exposure.camera import capture_design
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.render.samplers import DEFAULT_SAMPLER, SAMPLERS
from pacam_render.scenes import load_scene, psf_scene
from pacam_render.sensor.apply import SensorTarget

FIGURES = Path(__file__).with_name("figures")
DOCS = Path(__file__).resolve().parents[1] / "docs"
WINDOW = {"width": 1280, "height": 960, "crop": (200, 560, 200, 120)}
"""The train window at full scale: the near train (1.4 px/ms) over the backdrop."""


def capture(spec: CaptureSpec, desc=None):
    return render_capture(spec, progress=False, truth=False, description=desc)


def two_seeds(spec: CaptureSpec, desc=None) -> tuple[float, float, float, float, np.ndarray]:
    """(two-seed sigma, mean recorded sigma, mean wall seconds, mean CPU seconds, mean image)
    of a capture. CPU seconds (every thread of this process) hold when the machine is shared;
    wall seconds do not."""
    cpu0 = time.process_time()
    a = capture(spec, desc)
    b = capture(CaptureSpec.geometric(**{**spec.__dict__, "seed": spec.seed + 1}), desc)
    cpu = 0.5 * (time.process_time() - cpu0)
    sigma = float(np.sqrt(np.mean((a.image - b.image) ** 2) / 2))
    recorded = 0.5 * (a.record.render_error.mc_sigma + b.record.render_error.mc_sigma)
    seconds = 0.5 * (a.record.render_seconds + b.record.render_seconds)
    return sigma, recorded, seconds, cpu, 0.5 * (a.image + b.image)


def sampler_rows(spps, samplers=SAMPLERS) -> list[dict]:
    rows = []
    for spp in spps:
        base = None
        for name in samplers:
            spec = CaptureSpec.geometric(
                scene="train", mode="coded", spp=spp, sampler=name, **WINDOW
            )
            sigma, recorded, t, cpu, mean = two_seeds(spec)
            eff, eff_cpu = 1.0 / (sigma**2 * t), 1.0 / (sigma**2 * cpu)
            if base is None:
                base = (eff, mean, sigma, eff_cpu)
            joint = np.sqrt(sigma**2 + base[2] ** 2) / np.sqrt(2)  # sigma of two-seed means
            bias = float(np.mean(mean - base[1]) / (joint / np.sqrt(mean.size)))
            rows.append(
                {
                    "spp": spp,
                    "sampler": name,
                    "sigma (two seeds)": sigma,
                    "sigma recorded": recorded,
                    "seconds": t,
                    "1/(sigma^2 t)": eff,
                    "vs independent": eff / base[0],
                    "CPU seconds": cpu,
                    "vs independent, CPU": eff_cpu / base[3],
                    "mean - independent's (SE)": bias,
                }
            )
            print(rows[-1], flush=True)
    return rows


@contextlib.contextmanager
def midpoint_rule():
    """The earlier captures' time steps: geometry and rays at each step's mid-time."""
    stratified = integrate.step_time
    integrate.step_time = lambda t0, t1, u: 0.5 * (t0 + t1)
    try:
        yield
    finally:
        integrate.step_time = stratified


def _streak(step_px: float, spp: int, seed: int, passes: int = 4):
    spec = CaptureSpec.geometric(
        scene="psf", mode="normal", width=80, height=8, spp=spp, seed=seed,
        max_step_px=step_px, passes=passes, sampler="independent",
    )  # fmt: skip
    cam = capture_design(spec).with_(focus_distance_mm=500.0)
    return capture(spec, psf_scene(500.0, 1.3, camera=cam, radius_mm=0.05))


def _train(step_px: float, spp: int, seed: int, passes: int = 2):
    spec = CaptureSpec.geometric(
        scene="train", mode="coded", spp=spp, seed=seed, max_step_px=step_px, passes=passes,
        **WINDOW,
    )  # fmt: skip
    return capture(spec)


def time_step_rows(full: bool) -> list[dict]:
    """Error of each rule and step against a fine stratified reference (noise removed)."""
    rows = []
    # spp per pass at least one sampler render per step (4 spp x 512 steps for the train's
    # 0.125 px reference): below that a pass joins steps (merge_windows), not what is measured
    cases = [
        ("moving point", _streak, 0.05, 8192, (0.25, 0.5, 1.0, 2.0, 6.0), 1024),
        ("train window", _train, 0.125, 16384 if full else 8192, (0.25, 0.5, 1.0, 2.0), 2048),
    ]
    for name, make, fine_px, fine_spp, steps, spp in cases:
        ref = make(fine_px, fine_spp, 100)
        ref_var = float(np.mean(ref.mc_sigma**2))
        for rule in ("stratified", "midpoint"):
            for step in steps:
                with midpoint_rule() if rule == "midpoint" else contextlib.nullcontext():
                    cap = make(step, spp, 0)
                err2 = float(np.mean((cap.image - ref.image) ** 2)) - ref_var
                sigma = cap.record.render_error.mc_sigma
                uncounted = np.sqrt(max(err2 - sigma**2, 0.0))
                t = cap.record.render_seconds
                rows.append(
                    {
                        "case": name,
                        "rule": rule,
                        "max_step_px": step,
                        "steps": cap.record.n_steps,
                        "spp": cap.record.effective_spp,
                        "RMS error": np.sqrt(max(err2, 0.0)),
                        "recorded sigma": sigma,
                        "error not in sigma": uncounted,
                        "seconds": t,
                        "1/(error^2 t)": 1.0 / (max(err2, 1e-30) * t),
                    }
                )
                print(rows[-1], flush=True)
    return rows


@contextlib.contextmanager
def shifted_grid():
    """One time draw per pass, shared by its steps: a randomly shifted grid of times (the
    steps' times one stream), instead of an independent draw per step."""
    jittered = integrate.step_draws

    def shared(seed, j, k):
        return jittered(seed, j, k)[0], jittered(seed, j, 2**31)[1]

    integrate.step_draws = shared
    try:
        yield
    finally:
        integrate.step_draws = jittered


def shifted_rows() -> list[dict]:
    """Jittered times against a shifted grid, two seeds each, against a fine reference."""
    rows = []
    cases = [
        ("moving point", _streak, (0.05, 8192, 100), ((0.5, 1024), (1.0, 1024), (2.0, 1024))),
        ("train window", _train, (0.125, 8192, 100), ((0.5, 2048), (1.0, 2048), (2.0, 2048))),
    ]
    for name, make, ref_args, runs in cases:
        ref = make(*ref_args)
        ref_var = float(np.mean(ref.mc_sigma**2))
        for rule in ("jittered", "shifted grid"):
            for step, spp in runs:
                with shifted_grid() if rule == "shifted grid" else contextlib.nullcontext():
                    caps = [make(step, spp, seed) for seed in (0, 1)]
                err2 = [float(np.mean((c.image - ref.image) ** 2)) - ref_var for c in caps]
                rows.append(
                    {
                        "case": name,
                        "times": rule,
                        "max_step_px": step,
                        "spp": spp,
                        "RMS error (2 seeds)": float(np.sqrt(max(np.mean(err2), 0.0))),
                        "recorded sigma (2 seeds)": float(
                            np.sqrt(np.mean([c.record.render_error.mc_sigma**2 for c in caps]))
                        ),
                    }
                )
                print(rows[-1], flush=True)
    return rows


SCENE_WINDOWS = {
    "train": (128, 259, 512, 461),
    "soccer": (360, 240, 560, 480),
    "walker": (380, 0, 520, 960),
}
"""Windows of the full 1280x960 sensor around each scene's subject."""


def bounce_rows(full: bool) -> list[dict]:
    """Light added by the bounces past each depth; two seeds give its noise-free size."""
    from pacam_render.sensor.apply import sensor_sigma
    from pacam_render.sensor.model import SensorModel

    icx = SensorModel.from_preset("grasshopper-icx285")
    rows = []
    spp = 1024 if full else 256
    for scene, crop in SCENE_WINDOWS.items():
        images, seconds = {}, {}
        for depth in (2, 3, 4, 8):
            desc = load_scene(scene)
            desc.integrator = {"type": "path", "max_depth": depth}
            pair = []
            for seed in (0, 1):
                spec = CaptureSpec.geometric(
                    scene=scene, mode="reference", width=1280, height=960, crop=crop,
                    spp=spp, seed=seed,
                )  # fmt: skip
                cap = capture(spec, desc)
                pair.append(cap)
            images[depth] = [c.image for c in pair]
            seconds[depth] = np.mean([c.record.render_seconds for c in pair])
        rec = pair[0].record
        level = float(np.mean(images[8][0]))
        targets = {light: 0.2 * sensor_sigma(rec, icx, light, level) for light in (300.0, 10000.0)}
        for depth in (2, 3, 4):
            # the bounces past `depth`, seed by seed (the shared first bounces cancel); the two
            # seeds are independent, so E[d1 d2] is the contribution's own mean square
            d1 = images[8][0] - images[depth][0]
            d2 = images[8][1] - images[depth][1]
            rms = float(np.sqrt(max(np.mean(d1 * d2), 0.0)))
            rows.append(
                {
                    "scene": scene,
                    "max_depth": depth,
                    "light past it (mean)": float(np.mean(d1 + d2) / 2),
                    "light past it (RMS)": rms,
                    "share of the light": float(np.mean(d1 + d2) / 2 / level),
                    "target at 300": targets[300.0],
                    "target at 10^4": targets[10000.0],
                    "seconds vs depth 8": seconds[depth] / seconds[8],
                }
            )
            print(rows[-1], flush=True)
    return rows


def seconds_rows(ref_spp: int, spps: tuple[int, ...]) -> list[dict]:
    """Monte Carlo sigma against seconds on the train window, and the midpoint's error."""
    rows = []
    ref = _train(0.125, ref_spp, 100)
    ref_var = float(np.mean(ref.mc_sigma**2))
    for label, sampler, rule in (
        (f"{DEFAULT_SAMPLER} (default)", DEFAULT_SAMPLER, "stratified"),
        ("independent", "independent", "stratified"),
        ("independent, midpoint rule", "independent", "midpoint"),
    ):
        for spp in spps:
            spec = CaptureSpec.geometric(
                scene="train", mode="coded", spp=spp, sampler=sampler, **WINDOW
            )
            cpu0 = time.process_time()
            with midpoint_rule() if rule == "midpoint" else contextlib.nullcontext():
                cap = capture(spec)
            cpu = time.process_time() - cpu0
            err = np.sqrt(max(float(np.mean((cap.image - ref.image) ** 2)) - ref_var, 0.0))
            rows.append(
                {
                    "capture": label,
                    "spp": cap.record.effective_spp,
                    "seconds": cap.record.render_seconds,
                    "CPU seconds": cpu,
                    "recorded sigma": cap.record.render_error.mc_sigma,
                    "error vs reference": err,
                }
            )
            print(rows[-1], flush=True)
    _plot_seconds(rows, ref.record.light_factor)
    return rows


def _plot_seconds(rows: list[dict], lf: float) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for label in dict.fromkeys(r["capture"] for r in rows):
        rs = [r for r in rows if r["capture"] == label]
        t = [r["CPU seconds"] for r in rs]
        (line,) = ax.plot(t, [r["error vs reference"] / lf for r in rs], "o-", label=label)
        if "midpoint" not in label:
            sig = [r["recorded sigma"] / lf for r in rs]
            ax.plot(t, sig, "x--", color=line.get_color(), label=f"{label}: recorded sigma")
    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):  # plain numbers, not powers of ten, on a short range
        axis.set_major_formatter(ScalarFormatter())
        axis.set_minor_formatter(ScalarFormatter())
    ax.set_xlabel("CPU seconds of the render (all threads; wall time on 2 idle cores ~ half)")
    ax.set_ylabel("error of the capture, white = 1 (RMS over the window)")
    ax.set_title("coded train, 200x120 window at full scale")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    fig.tight_layout()
    FIGURES.mkdir(exist_ok=True)
    fig.savefig(FIGURES / "render_error_vs_seconds.png", dpi=100)
    shutil.copy(FIGURES / "render_error_vs_seconds.png", DOCS / "render_error.png")
    plt.close(fig)


def overhead_rows() -> list[dict]:
    """The planner's cost model, in pixel-samples: a step's fixed cost o from two fixed-spp
    coded captures of the train window at 4 and 64 samples per step (t = steps o + c spp
    pixels), and a pass's own from short captures of 512 spp in 2 and in 32 passes (their
    difference is 30 passes' fixed cost, less their steps'). Wall and CPU seconds."""
    runs = {}
    for key, mode, spp, passes in (
        ("lo", "coded", 2 * 128 * 4, 2),
        ("hi", "coded", 2 * 128 * 64, 2),
        ("few", "short", 512, 2),
        ("many", "short", 512, 32),
    ):
        spec = CaptureSpec.geometric(scene="train", mode=mode, spp=spp, passes=passes, **WINDOW)
        cpu0 = time.process_time()
        cap = capture(spec)
        runs[key] = (cap, {"wall": cap.record.render_seconds, "CPU": time.process_time() - cpu0})
    px = runs["lo"][0].image.shape[0] * runs["lo"][0].image.shape[1]
    rows = []
    for clock in ("wall", "CPU"):
        (lo, t_lo), (hi, t_hi) = runs["lo"], runs["hi"]
        c = (t_hi[clock] - t_lo[clock]) / ((hi.record.effective_spp - lo.record.effective_spp) * px)
        o = (t_lo[clock] - c * lo.record.effective_spp * px) / (2 * lo.record.n_steps)
        (_, t_few), (many, t_many) = runs["few"], runs["many"]
        per_pass = (t_many[clock] - t_few[clock]) / 30 - many.record.n_steps * o
        rows.append(
            {
                "clock": clock,
                "s per pixel-sample (c)": c,
                "step: o / c": o / c,
                "in use (step)": progress.STEP_OVERHEAD_PX_SAMPLES,
                "pass: its own / c": per_pass / c,
                "in use (pass)": progress.PASS_OVERHEAD_PX_SAMPLES,
                "short steps per pass": many.record.n_steps,
            }
        )
        print(rows[-1], flush=True)
    return rows


@contextlib.contextmanager
def one_size_planner():
    """The earlier planner: passes of the main size, added one at a time until the target."""

    def add_one(sched, stats, exp):
        if sched.done_passes >= sched.planned and sched.spp + sched.groups[-1][0] <= sched.max_spp:
            sched.planned += 1

    saved, progress.replan = progress.replan, add_one
    try:
        yield
    finally:
        progress.replan = saved


def planner_rows() -> list[dict]:
    """The re-plan against one pass size, each to the crossover study's target: 0.2x the
    ICX285's noise at 10^4 photons/px/ms (the lowest sensor noise a crossover render feeds)."""
    target = SensorTarget(0.2, (("grasshopper-icx285", 1e4),))
    rows = []
    for mode in ("short", "normal", "coded"):
        for planner in ("re-plan (default)", "one size"):
            spec = CaptureSpec.geometric(scene="train", mode=mode, **WINDOW)
            cpu0 = time.process_time()
            with one_size_planner() if planner == "one size" else contextlib.nullcontext():
                cap = render_capture(spec, progress=False, truth=False, target=target)
            err = cap.record.render_error
            sizes = dict.fromkeys(err.pass_spp)
            rows.append(
                {
                    "mode": mode,
                    "planner": planner,
                    "target": err.target_sigma,
                    "mc_sigma": err.mc_sigma,
                    "met": err.target_met,
                    "passes": err.passes,
                    "pass sizes (spp)": " ".join(f"{s}x{err.pass_spp.count(s)}" for s in sizes),
                    "spp": err.spp,
                    "seconds": cap.record.render_seconds,
                    "CPU seconds": time.process_time() - cpu0,
                }
            )
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="more spp (slower)")
    ap.add_argument("--quick", action="store_true", help="fewer spp: about a third of the time")
    ap.add_argument("--note", default="", help="appended to each table's caption")
    ap.add_argument("--spp", type=int, nargs="*", help="part 1's spp (default 1024 4096)")
    ap.add_argument("--samplers", nargs="*", default=list(SAMPLERS), help="part 1's samplers")
    ap.add_argument("--part", type=int, nargs="*", default=[1, 2, 3, 4, 5, 6])
    args = ap.parse_args()
    t0 = time.perf_counter()
    note = f"; {args.note}" if args.note else ""
    ref_spp = 4096 if args.quick else 8192
    if 1 in args.part:
        record(
            "Render error: samplers at equal spp (issue 25)",
            sampler_rows(args.spp or ((1024,) if args.quick else (1024, 4096)), args.samplers),
            "coded train, 200x120 window at (200, 560) of the 1280x960 sensor, 0.5 px steps "
            "(128 per pass), 2 passes; sigma from two seeds, t = render_seconds (wall) or the "
            "process's CPU seconds (all threads); bias: the "
            "mean difference from independent in standard errors" + note,
        )
    if 2 in args.part:
        record(
            "Render error: time steps, stratified random times against the midpoint rule",
            time_step_rows(args.full),
            "error against a fine stratified reference (moving point: 0.05 px, 8192 spp; "
            "train: 0.125 px, 8192 spp, 16384 with --full), its noise removed; 'error not in "
            "sigma' is the part the recorded Monte Carlo sigma does not cover (the bias)" + note,
        )
    if 3 in args.part:
        record(
            "Render error: light past each path depth, against a study's noise target",
            bounce_rows(args.full),
            "reference camera, full pixel scale; white = 1; the RMS is E[d1 d2] of two seeds "
            "(noise-free); targets: 0.2 x the ICX285's noise at the scene's mean level" + note,
        )
    if 4 in args.part:
        record(
            "Render error against seconds: a coded capture of the train window",
            seconds_rows(ref_spp, (1024, 2048) if args.quick else (1024, 2048, 4096)),
            f"error against a {ref_spp} spp, 0.125 px reference (its noise removed); capture "
            "units" + note,
        )
    if 5 in args.part:
        record(
            "Render error: one time draw per pass (a shifted grid) against jittered step times",
            shifted_rows(),
            "error against a fine jittered reference (noise removed), mean square over two "
            "seeds; the recorded sigma is the captures' own (4 passes for the point, 2 for the "
            "train)" + note,
        )
    if 6 in args.part:
        record(
            "Render error: the noise-target planner, a step's fixed cost",
            overhead_rows(),
            "train, 200x120 window; coded: 128 steps per pass, 2 passes at 4 and 64 spp per "
            "step; short: 512 spp in 2 and in 32 passes; costs beyond the samples, in "
            "pixel-samples" + note,
        )
        record(
            "Render error: the noise-target planner, re-plan against one pass size",
            planner_rows(),
            "train, 200x120 window at full scale, 0.5 px steps, ldsampler; target 0.2x the "
            "ICX285's noise at 10^4 photons/px/ms (capture units); 'pass sizes' lists spp x "
            "passes, pilot first" + note,
        )
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
