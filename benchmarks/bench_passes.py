"""Deterministic sample passes vs one ``mi.render`` call (issue 12, probe 3).

One render of ``spp`` samples is nondeterministic when ``spp`` is not a power of two: a pixel's
samples straddle two of Dr.Jit's LLVM blocks and two threads add to it in a varying order.
:func:`pacam_render.render.passes.render_passes` splits the samples into power-of-two passes.
For each spp this measures, side by side in one run, both ways' median time (3 renders each,
interleaved, after a warm-up) and how many pixels differ between the 3 same-seed renders.

    python benchmarks/bench_passes.py [--size 320x240]
"""

from __future__ import annotations

import argparse
import time

import mitsuba as mi
import numpy as np
from common import median_spread, record

from pacam_render.exposure.camera import capture_design, mode_camera
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.render.backend import select_variant
from pacam_render.render.passes import render_passes, split_spp
from pacam_render.render.registry import sensor_entry
from pacam_render.scenes import load_scene


def scene_for(width: int, height: int):
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=width, height=height)
    cam, params = mode_camera(capture_design(spec), "coded")
    return load_scene("train").load(sensor=sensor_entry(spec, cam, params, cam.exposure_ms))


def row(scene, spp: int, repeat: int = 3) -> dict:
    ways = {
        "one call": lambda: np.array(mi.render(scene, spp=spp, seed=3), dtype=np.float64),
        "passes": lambda: render_passes(scene, spp, 3),
    }
    times = {k: [] for k in ways}
    images = {k: [] for k in ways}
    for f in ways.values():
        f()  # warm-up: kernel compilation
    for _ in range(repeat):
        for k, f in ways.items():
            t0 = time.perf_counter()
            images[k].append(f())
            times[k].append(time.perf_counter() - t0)
    out = {"spp": spp, "passes": len(split_spp(spp, 1))}
    for k in ways:
        out[f"{k} s"] = median_spread(times[k])[0]
        out[f"{k} differing px"] = max(int((im != images[k][0]).any(-1).sum()) for im in images[k])
    out["time ratio"] = out["passes s"] / out["one call s"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    select_variant()
    scene = scene_for(w, h)
    rows = [row(scene, spp) for spp in (19, 64, 300, 1000, 4095)]
    record(
        "Deterministic sample passes vs one mi.render call (issue 12)",
        rows,
        notes=f"train scene, coded, static render of the whole exposure, {w}x{h}; differing px: "
        "the most pixels that differ between 3 same-seed renders; ratio = passes / one call",
    )


if __name__ == "__main__":
    main()
