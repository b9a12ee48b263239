"""The planner's cost model against the renders it predicts (issue 46, item 6).

``pacam render`` (and the demo, ``validate-scene``) says how long its renders will take before
they start (:mod:`pacam_render.exposure.render_time`): seconds per render call, per first call in a
process, per million samples and per render, fitted to this machine's earlier renders. This
benchmark:

1. renders a calibration set of train captures (fresh ``pacam render`` processes, as a user runs
   them; 80x60 to 640x480 windows, 64 to 1024 spp, four modes, diffraction off, and two with
   ``auto``'s preview: a second call in its process) into an empty history, and fits the
   rates to them (the reference rates the package ships,
   :data:`~pacam_render.exposure.render_time.REFERENCE_RATES`);
2. predicts a held-out set (other sizes, spp and modes, one with diffraction ``auto``) from those
   rates, renders it, and reports the estimate's error against the render calls' own seconds
   (what it predicts) and against the command's wall time (which adds Python's and Mitsuba's
   start, about 2-4 s, and the optics budget);
3. does the same for PSF renders (particle tracing): fitted to ``validate-psf --quick``'s,
   checked on a held-out grid, serially in this process (the wall time adds the analytic
   models and the comparisons).

    python benchmarks/bench_cost_model.py [HISTORY.jsonl]   (keeps the calibration history)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import record

from pacam_render.exposure import render_time as cost
from pacam_render.exposure.spec import CaptureSpec

CALIBRATION = [  # mode, window (w, h), spp, diffraction
    ("coded", (80, 60), 64, "off"),
    ("coded", (160, 120), 256, "off"),
    ("coded", (320, 240), 64, "off"),
    ("reference", (320, 240), 128, "off"),
    ("normal", (160, 120), 512, "off"),
    ("coded", (160, 120), 1024, "off"),
    ("coded", (480, 360), 128, "off"),
    ("short", (320, 240), 256, "off"),
    ("coded", (640, 480), 64, "off"),
    ("coded", (240, 180), 128, "auto"),
    ("normal", (320, 240), 256, "auto"),
    ("short", (640, 480), 512, "off"),
    ("reference", (480, 360), 1024, "off"),
]
HELD_OUT = [
    ("coded", (240, 180), 512, "off"),
    ("normal", (400, 300), 128, "off"),
    ("coded", (200, 120), 2048, "off"),
    ("reference", (640, 480), 64, "off"),
    ("coded", (160, 120), 256, "auto"),
    ("short", (672, 701), 256, "off"),
    ("coded", (672, 701), 256, "off"),
]


def _spec(mode, size, spp, diffraction) -> CaptureSpec:
    w, h = size
    return CaptureSpec(mode=mode, scene="train", width=1280, height=960, crop=(0, 19, w, h),
                       spp=spp, diffraction=diffraction)  # fmt: skip


def _render(case, out: Path, env: dict) -> tuple[float, float]:
    """(wall s of the command, summed seconds of its render calls from the history)."""
    mode, (w, h), spp, diffraction = case
    before = _history_seconds(env)
    cmd = [sys.executable, "-m", "pacam_render", "render", "train", "--mode", mode, "--crop",
           f"0,19,{w},{h}", "--spp", str(spp), "--diffraction", diffraction, "--out", str(out),
           "--force", "--quiet"]  # fmt: skip
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, capture_output=True)
    return time.perf_counter() - t0, _history_seconds(env) - before


def _history_seconds(env: dict) -> float:
    path = Path(env["PACAM_RENDER_TIMES"])
    if not path.exists():
        return 0.0
    return sum(json.loads(x)["seconds"] for x in path.read_text().splitlines() if x.strip())


def _psf_rows(d: Path) -> list[dict]:
    """PSF renders: fit to ``validate-psf --quick`` (serial, in this process), then predict a
    held-out grid (other depths, F-numbers and speeds) and render it."""
    from pacam_render.experiments import validate_psf as vp
    from pacam_render.psf_render.render import psf_history_key

    key = psf_history_key()

    def rendered() -> float:
        path = Path(os.environ["PACAM_RENDER_TIMES"])
        rows = [json.loads(x) for x in path.read_text().splitlines()] if path.exists() else []
        return sum(r["seconds"] for r in rows if r["key"] == key)

    vp.run(vp.QUICK, d / "psf_cal", progress=False, plots=False)
    rates = cost.rates(key)
    held = vp.Grid("held out", (400.0, 1000.0), (5.6, 12.0), (0.25, 0.75), 1 << 17)
    est = vp.estimate(held)
    before = rendered()
    t0 = time.perf_counter()
    vp.run(held, d / "psf_held", progress=False, plots=False)
    wall, renders = time.perf_counter() - t0, rendered() - before
    fitted = ", ".join(f"{v:.3g} s per {k}" for k, v in zip(cost.FIELDS, rates.per))
    print(f"PSF rates fitted: {fitted} ({rates.basis})")
    return [{
        "case": "validate-psf grid 400/1000 mm x F5.6/F12 x 0.25/0.75 (serial)",
        "predicted s": est.seconds, "render calls s": renders, "wall s": wall,
        "error vs renders": est.seconds / renders - 1, "error vs wall": est.seconds / wall - 1,
    }], fitted  # fmt: skip


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "PACAM_RENDER_TIMES": str(Path(d) / "history.jsonl")}
        os.environ["PACAM_RENDER_TIMES"] = env["PACAM_RENDER_TIMES"]
        _render(CALIBRATION[0], Path(d) / "warm", env)  # the kernel cache, once
        Path(env["PACAM_RENDER_TIMES"]).unlink()
        for case in CALIBRATION:
            _render(case, Path(d) / "out", env)
        rates = cost.rates("llvm_ad_rgb")
        fitted = ", ".join(f"{v:.3g} s per {k}" for k, v in zip(cost.FIELDS, rates.per))
        print(f"fitted: {fitted} ({rates.basis})")
        if len(sys.argv) > 1:  # keep the calibration history for inspection
            Path(sys.argv[1]).write_text(Path(env["PACAM_RENDER_TIMES"]).read_text())
        rows = []
        for case in HELD_OUT:
            est = cost.estimate_capture(_spec(*case))
            wall, renders = _render(case, Path(d) / "out", env)
            mode, (w, h), spp, diffraction = case
            rows.append({
                "case": f"{mode} {w}x{h} {spp} spp, diffraction {diffraction}",
                "predicted s": est.seconds, "render calls s": renders, "wall s": wall,
                "error vs renders": est.seconds / renders - 1,
                "error vs wall": est.seconds / wall - 1,
            })  # fmt: skip
        psf_rows, psf_fitted = _psf_rows(Path(d))
    errs = np.abs([r["error vs renders"] for r in rows])
    record(
        "Cost model: predicted render time against measured (held-out captures, a PSF grid)",
        rows + psf_rows,
        f"rates fitted to {len(CALIBRATION)} calibration captures: {fitted}; held out: median "
        f"|error| {np.median(errs):.0%}, largest {errs.max():.0%} against the render calls' "
        f"seconds; PSF renders fitted to validate-psf --quick: {psf_fitted}",
    )


if __name__ == "__main__":
    main()
