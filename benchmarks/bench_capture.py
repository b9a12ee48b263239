"""Capture benchmarks (issue 4).

Cost of a moving-geometry capture against a static render of the same scene (motion removed) at
equal total spp, 1280x960, as a ratio measured side by side. Target <= 1.3x. (The time steps'
error, with stratified random times against the earlier midpoint rule, is measured by
``bench_render_error.py``, part 2.)

    python benchmarks/bench_capture.py [--full]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from common import median_spread, record

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.scenes import load_scene


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def cost_rows(width: int, height: int, spp: int, repeat: int) -> list[dict]:
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=width, height=height, spp=spp)
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="3 repeats")
    args = ap.parse_args()
    record(
        "Moving-geometry capture vs static render at equal total spp (issue 4)",
        cost_rows(1280, 960, 256, 3 if args.full else 1),
        notes="train scene, coded mode; static = the same scene with its motion removed, "
        "one render pass; target ratio <= 1.3",
    )


if __name__ == "__main__":
    main()
