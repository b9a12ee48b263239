"""Capture benchmarks (issue 4).

1. Cost of a moving-geometry capture against a static render of the same scene (motion removed)
   at equal total spp, 1280x960, as a ratio measured side by side. Target <= 1.3x.
2. Time-step discretisation error against steps per pattern and seconds: relative L1 of a
   moving point's coded capture (PSF scene, ptracer, so little Monte Carlo noise) at
   max_step_px in {4, ..., 0.125} against a 1/32-px reference, with the Monte Carlo floor (two
   seeds at the reference step) alongside.

    python benchmarks/bench_capture.py [--full]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from common import median_spread, record

from pacam_render.exposure.capture import CaptureSpec, capture_design, render_capture
from pacam_render.scenes import load_scene, psf_scene


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def cost_rows(width: int, height: int, spp: int, repeat: int) -> list[dict]:
    spec = CaptureSpec(scene="train", mode="coded", width=width, height=height, spp=spp)
    moving_desc = load_scene("train")
    static_desc = dataclasses.replace(moving_desc, motions={})
    render_capture(
        dataclasses.replace(spec, spp=1), progress=False, truth=False
    )  # compile kernels once
    render_capture(
        dataclasses.replace(spec, spp=1), progress=False, truth=False, description=static_desc
    )
    moving, static, meta = [], [], None
    for _ in range(repeat):  # interleaved, so load changes hit both alike
        cap, t = timed(
            lambda: render_capture(spec, progress=False, truth=False, description=moving_desc)
        )
        moving.append(t)
        meta = cap.meta
        _, t = timed(
            lambda: render_capture(spec, progress=False, truth=False, description=static_desc)
        )
        static.append(t)
    m, ms = median_spread(moving)
    s, ss = median_spread(static)
    return [
        {
            "size": f"{width}x{height}",
            "total_spp": spp,
            "steps": meta["n_steps"],
            "geometry_updates": meta["n_geometry_updates"],
            "moving_s": m,
            "static_s": s,
            "ratio": m / s,
            "ratio_range": f"{min(moving) / max(static):.3f}-{max(moving) / min(static):.3f}",
        }
    ]


def step_rows(spp: int) -> tuple[list[dict], float]:
    """A moving point (PSF scene, ptracer: little Monte Carlo noise) isolates the steps' error."""
    base = CaptureSpec(scene="psf", mode="coded", width=128, height=24, spp=spp)
    desc = psf_scene(500.0, 1.0, camera=capture_design(base), radius_mm=0.2)  # 1 px/ms here

    def run(step: float, seed: int = 0):
        spec = dataclasses.replace(base, max_step_px=step, seed=seed)
        return timed(lambda: render_capture(spec, progress=False, truth=False, description=desc))

    (ref, _), (twin, _) = run(1 / 32), run(1 / 32, seed=1)
    norm = np.abs(ref.image).sum()
    floor = float(np.abs(twin.image - ref.image).sum() / norm)
    rows = []
    for step in (4.0, 2.0, 1.0, 0.5, 0.25, 0.125):
        cap, t = run(step)
        rows.append(
            {
                "max_step_px": step,
                "steps_per_pattern": cap.meta["n_steps"] / 16,
                "seconds": t,
                "rel_L1_vs_ref": float(np.abs(cap.image - ref.image).sum() / norm),
                "mc_floor": floor,
            }
        )
    return rows, floor


def plot(rows, path) -> None:
    x = [r["steps_per_pattern"] for r in rows]
    y = [r["rel_L1_vs_ref"] for r in rows]
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    ax.loglog(x, y, "o-", label="stepped capture vs 1/32-px reference")
    ax.axhline(rows[0]["mc_floor"], ls=":", color="k", label="Monte Carlo floor (two seeds)")
    ax.set_xlabel("time steps per pattern")
    ax.set_ylabel("relative L1")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Time-step error: a point moving 1 px/ms, coded")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="3 repeats and 1024 spp for the steps")
    args = ap.parse_args()
    record(
        "Moving-geometry capture vs static render at equal total spp (issue 4)",
        cost_rows(1280, 960, 256, 3 if args.full else 1),
        notes="train scene, coded mode; static = the same scene with its motion removed, "
        "one render pass; target ratio <= 1.3",
    )
    rows, _ = step_rows(8192 if args.full else 2048)
    record(
        "Time-step discretisation error vs steps and seconds (issue 4)",
        rows,
        notes="PSF scene (a point moving 1 px/ms), coded, 128x24, ptracer; total spp fixed "
        "and shared among the steps; reference 1/32 px per step",
    )
    from pathlib import Path

    out = Path(__file__).with_name("figures") / "capture_time_steps.png"
    out.parent.mkdir(exist_ok=True)
    plot(rows, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
