"""The study engine: throughput of 1 against 2 Dask workers on one 12-point study (issue 14).

The same study (12 renders of the train scene, one point each) runs side by side in one
process: serially in-process (``--workers 0``), then on a LocalCluster of 1 and of 2 spawned
workers (Dr.Jit threads = cores / workers), and on 1 worker of one thread: with threads at
cores / workers the single worker already renders on every core, so the engine's own scaling
is the 1-thread worker against 2 workers. Each engine's study goes into a fresh folder and is
timed from the call to the report. From the rows' own in-task times it derives:

* throughput (points/s) and the ratio 2 workers / 1 worker;
* cluster start-up (timed alone) and per-task overhead: wall - start-up - the tasks' own time,
  per task, on 1 worker (scheduling, serialisation, result handling);
* the scene load inside each task (timed alone), as a fraction of a task;
* a projection to N workers, T(N) = start-up + ceil(tasks / N) x (task + overhead), stated as a
  projection from these figures, not a measurement.

    python benchmarks/bench_study.py [--size 320x240] [--spp 16]
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

from common import record

from pacam_render.study import run_study
from pacam_render.study.report import load_rows
from pacam_render.study.spec import parse_study


def study(width: int, height: int, spp: int):
    return parse_study(
        {
            "study": {"name": "bench", "report": "table"},
            "render": {"width": width, "height": height, "spp": spp, "max_step_px": 1.0},
            "grid": {
                "mode": ["coded", "normal", "short", "levin"],
                "speed_px_per_ms": [0.7, 1.0, 1.4],
                "light_level": [300.0],
            },
        }
    )


def timed_run(spec, workers: int, root: Path, threads=None) -> tuple[float, list[dict]]:
    out = root / f"w{workers}t{threads}"
    t0 = time.perf_counter()
    run_study(spec, out, workers=workers, progress=False, threads=threads)
    return time.perf_counter() - t0, load_rows(out)


def cluster_start_s() -> float:
    from pacam_render.study.engine import _client

    t0 = time.perf_counter()
    with _client(1, None) as client:
        client.run(lambda: None)
    return time.perf_counter() - t0


def scene_load_s() -> float:
    from pacam_render.render.backend import select_variant
    from pacam_render.scenes import load_scene

    select_variant()
    load_scene("train").load()  # warm the asset cache
    t0 = time.perf_counter()
    load_scene("train").load()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    spec = study(w, h, args.spp)
    n = len(spec.points)
    rows, walls = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for workers, threads in ((0, None), (1, None), (2, None), (1, 1)):
            wall, res = timed_run(spec, workers, Path(tmp), threads)
            walls[(workers, threads)] = wall
            task = sum(r["total_s"] for r in res) / n
            rows.append(
                {
                    "engine": "serial" if workers == 0 else f"{workers} worker(s)",
                    "Dr.Jit threads each": threads or os.cpu_count() // max(1, workers),
                    "points": n,
                    "wall s": wall,
                    "points/s": n / wall,
                    "mean task s": task,
                    "ok": sum(r["status"] == "ok" for r in res),
                }
            )
    start = cluster_start_s()
    load = scene_load_s()
    task = rows[1]["mean task s"]
    overhead = (walls[(1, None)] - start - n * task) / n
    ratio = walls[(1, None)] / walls[(2, None)]
    ratio_1t = walls[(1, 1)] / walls[(2, None)]
    proj = {N: start + math.ceil(n / N) * (task + overhead) for N in (1, 2, 4, 8, 16)}
    notes = (
        f"train scene, {w}x{h}, {args.spp} spp, {n} points = {n} renders; throughput ratio "
        f"2 workers / 1 worker = {ratio:.2f} with Dr.Jit's threads at cores / workers (the 1 "
        f"worker already renders on both cores), {ratio_1t:.2f} at one thread per worker (the "
        f"engine's own scaling; target 1.8); cluster start-up {start:.2f} s; "
        f"per-task overhead on 1 worker {overhead:.3f} s = {overhead / task:.1%} of a "
        f"{task:.2f} s task; scene load {load:.3f} s = {load / task:.1%} of a task (inside "
        "it). Projection, not measured, T(N) = start-up + ceil(points / N) x (task + "
        "overhead) with one-core tasks: " + ", ".join(f"N={k}: {v:.1f} s" for k, v in proj.items())
    )
    record("Study engine: 1 vs 2 Dask workers (issue 14)", rows, notes=notes)


if __name__ == "__main__":
    main()
