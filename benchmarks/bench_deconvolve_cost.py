"""What a deconvolution costs (issue 37 item 9): each method's peak memory and seconds against
its padded FFT grid and channels, the fit of :mod:`pacam_render.restore.deconvolve_cost`'s model to
them, and the model against measurements at sizes it was not fitted on.

Each measurement is one deconvolution in a fresh Python process (``--one``): a random image of
H x W px and C channels, a 17 x 17 box kernel, the method's defaults and noise sigma 0.01.
Memory is the peak RSS (VmHWM) over the RSS just before the call, so it counts every
array the method makes (scipy.fft's, scikit-image's and jax's included), and the packages it
imports on its first run (for ``pnp`` jax, scico and the network's weights, built before the
timing and counted here), and nothing made before. Seconds are the least of ``--repeat``
calls in that process (a shared machine only slows a call down); ``pnp`` runs once, its jit
compile included, as in a real run.

    python benchmarks/bench_deconvolve_cost.py              # fit on the small sizes
    python benchmarks/bench_deconvolve_cost.py --validate   # the model against larger sizes
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

FIT = {
    "wiener": [(96, 128), (192, 256), (384, 512)],
    "hl": [(96, 128), (192, 256), (384, 512)],
    "tv": [(96, 128), (192, 256), (384, 512)],
    "rl": [(96, 128), (192, 256), (384, 512)],
    "uwiener": [(96, 128), (192, 256), (384, 512)],
    "bm3d": [(96, 128), (192, 256)],
    "pnp": [(96, 128), (192, 256)],
}
"""Sizes the constants are fitted on, per method (each with 1 and 3 channels)."""
VALIDATE = [
    ("wiener", 960, 1280, 3),
    ("hl", 480, 640, 3),
    ("hl", 960, 1280, 3),
    ("tv", 960, 1280, 1),
    ("rl", 480, 640, 3),
    ("pnp", 240, 320, 3),
]
"""Sizes the model is checked on, none of them fitted."""
KERNEL = 17


def _rss() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _peak_rss() -> int:
    """This process's peak RSS (VmHWM). Not ``ru_maxrss``, which a child started from a larger
    process (a test run) inherits: it read 430 MB for hl's 222 under pytest."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmHWM in /proc/self/status")


def one(method: str, h: int, w: int, c: int, repeat: int) -> dict:
    """One method on one size, in this process: peak bytes over the RSS before, seconds."""
    from pacam_render.restore.deconvolve import deconvolve
    from pacam_render.restore.deconvolve_cost import padded_grid

    rng = np.random.default_rng(0)
    image = rng.random((h, w, c) if c > 1 else (h, w)) * 0.5 + 0.25
    psf = np.ones((KERNEL, KERNEL)) / KERNEL**2
    kw = {"noise_sigma": 0.01} if method in ("wiener", "hl", "tv", "bm3d", "pnp") else {}
    base = _rss()
    if method == "pnp":  # jax, scico and the weights (counted), before the timing
        from pacam_render.restore.pnp import VARIANT, _network

        _network(VARIANT)
    seconds = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        deconvolve(image, psf, method, **kw)
        seconds.append(time.perf_counter() - t0)
    peak = _peak_rss()
    hp, wp = padded_grid((h, w), (KERNEL, KERNEL))
    return {
        "method": method,
        "h": h,
        "w": w,
        "c": c,
        "grid": hp * wp,
        "bytes": peak - base,
        "seconds": min(seconds),
    }


def measure(method: str, h: int, w: int, c: int, repeat: int) -> dict:
    """:func:`one` in a fresh process (its own peak RSS), one thread for BLAS."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    argv = [sys.executable, __file__, "--one", method, str(h), str(w), str(c), str(repeat)]
    out = subprocess.run(argv, capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def fit(rows: list[dict]) -> dict:
    """bytes = fixed + grid (shared + C per_channel), seconds = grid (shared + C per_channel),
    least squares over a method's rows."""
    g = np.array([r["grid"] for r in rows], float)
    c = np.array([r["c"] for r in rows], float)
    a = np.stack([np.ones_like(g), g, g * c], axis=1)
    mem = np.linalg.lstsq(a, np.array([r["bytes"] for r in rows], float), rcond=None)[0]
    sec = np.linalg.lstsq(a[:, 1:], np.array([r["seconds"] for r in rows]), rcond=None)[0]
    return {
        "fixed_MB": mem[0] / 1e6,
        "shared_B_per_px": mem[1],
        "channel_B_per_px": mem[2],
        "shared_us_per_px": sec[0] * 1e6,
        "channel_us_per_px": sec[1] * 1e6,
    }


def validate_rows(repeat: int) -> list[dict]:
    from pacam_render.restore.deconvolve_cost import deconvolve_cost

    rows = []
    for method, h, w, c in VALIDATE:
        m = measure(method, h, w, c, 1 if method == "pnp" else repeat)
        shape = (h, w, c) if c > 1 else (h, w)
        est = deconvolve_cost(shape, (KERNEL, KERNEL), method)
        rows.append(
            {
                "method": method,
                "image": f"{w}x{h}x{c}",
                "measured MB": m["bytes"] / 1e6,
                "model MB": est.method_bytes / 1e6,
                "ratio": est.method_bytes / m["bytes"],
                "measured s": m["seconds"],
                "model s": est.seconds,
            }
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", nargs=5, metavar=("METHOD", "H", "W", "C", "REPEAT"))
    ap.add_argument("--validate", action="store_true")
    ap.add_argument("--methods", nargs="*", default=list(FIT))
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    if args.one:
        m, h, w, c, r = args.one
        print(json.dumps(one(m, int(h), int(w), int(c), int(r))))
        return
    sys.path.insert(0, str(Path(__file__).parent))
    from common import record

    if args.validate:
        record(
            "Deconvolution cost model against measured peak memory and seconds (issue 37)",
            validate_rows(args.repeat),
            "sizes not fitted on; MB = 1e6 bytes over the RSS before the call",
        )
        return
    table = []
    for method in args.methods:
        rows = [
            measure(method, h, w, c, 1 if method in ("pnp", "bm3d") else args.repeat)
            for h, w in FIT[method]
            for c in (1, 3)
        ]
        table.append({"method": method, **fit(rows)})
    record("Deconvolution cost: fitted constants (issue 37)", table, f"{KERNEL} px kernel")


if __name__ == "__main__":
    main()
