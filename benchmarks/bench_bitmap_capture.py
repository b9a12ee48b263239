"""A bitmap schedule's capture against a disc schedule's, at equal samples (issue 46, item 4).

A user's 64-pattern slit design (F8, 20 ms) rendered 16x slower than a disc design: every time
step re-read, re-checked and re-tabulated the 64 full-display masks (1.3 s per step), and every
record re-compressed them. The tables now live as long as the masks do.

Three design files of one camera (64 patterns in 20 ms, F8, |s| <= 1.5 px/ms):

- ``disc``: the parabolic schedule (Eq. 11), a disc per pattern;
- ``raster``: the same discs as 1280x1024 LCoS bitmaps (equal open area, by construction);
- ``slit``: 64 vertical slits sweeping the lens along the parabola, each of the disc's area.

Each renders the train's 200x120 window at full scale (``pacam render --crop``),
diffraction off, at 512 and 2048 spp (a capture at the default noise target takes about 2000
at this window), after one warm-up of each, in ``--rounds`` interleaved rounds, each in a fresh
process as a user runs it. Time: the command's wall time, and the capture's ``render_seconds``
(scene, samples, truth layers, record; not the optics budget); ratio to ``disc`` in the same
round (median). ``--auto`` adds rounds with ``--diffraction auto`` against the setting it decides
asked for directly, at 512 spp: the preview's cost is the difference of the two walls.

    python benchmarks/bench_bitmap_capture.py [--rounds 3] [--auto]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import median_spread, record

from pacam_render.cli import main
from pacam_render.model.design_file import read_design
from pacam_render.model.masks import DISPLAY_SHAPE, disc_masks, pixel_centres_mm

RENDER = ["render", "train", "--crop", "400,500,200,120", "--quiet"]


def _designs(d: Path) -> dict[str, Path]:
    """The three design files (module docstring), written into ``d``."""
    disc = d / "disc.toml"
    assert main(["design", "--f-number", "8", "--max-velocity", "1.5", "--n-patterns", "64",
                 "--exposure", "20", "--lcos-rate", "4000", "--write", str(disc),
                 "--json"]) == 0  # fmt: skip
    cam = read_design(disc)
    centres = cam.pattern_centres_xy_mm()
    raster = disc_masks(centres, cam.R_mm, DISPLAY_SHAPE, cam.lcos_pitch_mm)
    x, y = pixel_centres_mm(DISPLAY_SHAPE, cam.lcos_pitch_mm)  # x falls with the column
    half_h = cam.R_mm  # slits as tall as the disc, as wide as gives its area
    half_w = np.pi * cam.R_mm**2 / (4 * half_h)
    slit = np.stack(
        [(np.abs(-x[None, :] - cx) <= half_w) & (np.abs(y[:, None]) <= half_h) for cx, _ in centres]
    ).astype(np.float32)
    out = {"disc": disc}
    for name, stack in (("raster", raster), ("slit", slit)):
        np.save(d / f"{name}.npy", stack)
        path = d / f"{name}.toml"
        assert main(["design", "--design", str(disc), "--masks", str(d / f"{name}.npy"),
                     "--write", str(path), "--json"]) == 0  # fmt: skip
        out[name] = path
    return out


def _render(design: Path, out: Path, extra: list, spp: int = 512) -> tuple[float, dict]:
    """One ``pacam render`` in a fresh process (what a user runs: no kernels or masks kept)."""
    cmd = [sys.executable, "-m", "pacam_render", *RENDER, "--spp", str(spp), "--design",
           str(design), *extra,
           "--out", str(out), "--force"]  # fmt: skip
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    return wall, json.loads((out / "capture.json").read_text())


def _preview_s(rec: dict) -> float:
    text = rec["optics_error"]["diffraction"]["decision"]
    return float(re.search(r"preview[^,]*, ([0-9.]+) s\)", text).group(1))


def _row(name: str, area: float, times: dict) -> dict:
    wall = [w for w, _ in times[name]]
    rend = [r["render_seconds"] for _, r in times[name]]
    ratio = [w / wd for w, (wd, _) in zip(wall, times["disc"])]
    rr = [r / rd["render_seconds"] for r, (_, rd) in zip(rend, times["disc"])]
    return {
        "schedule": name,
        "open area (mm^2)": round(float(area), 3),
        "spp": times[name][0][1]["effective_spp"],
        "wall s (median)": median_spread(wall)[0],
        "wall vs disc": median_spread(ratio)[0],
        "render_seconds (median)": median_spread(rend)[0],
        "render vs disc": median_spread(rr)[0],
        "preview s": "",
        "preview / capture": "",
    }


def _auto_row(name: str, design: Path, area: float, d: Path, rounds: int) -> dict:
    """``--diffraction auto`` against the setting it decides (``on`` or ``off``) asked for,
    each in fresh processes, ``rounds`` times: the preview's cost is the difference of the
    walls. Its own recorded seconds also hold the process's first render (kernel loading) and
    the diffraction kernels, which the capture or its optics budget would otherwise take."""
    auto, asked, pre = [], [], []
    for _ in range(rounds):
        wall, rec = _render(design, d / f"auto_{name}", ["--diffraction", "auto"])
        decision = rec["optics_error"]["diffraction"]["decision"]
        same = "on" if decision.startswith("auto: included") else "off"
        auto.append(wall)
        pre.append(_preview_s(rec))
        asked.append(_render(design, d / f"asked_{name}", ["--diffraction", same])[0])
    extra = [a - b for a, b in zip(auto, asked)]
    return {
        "schedule": f"{name}, diffraction auto (decided {same})",
        "open area (mm^2)": round(float(area), 3),
        "spp": rec["effective_spp"],
        "wall s (median)": median_spread(auto)[0],
        "wall vs disc": "",
        "render_seconds (median)": rec["render_seconds"],
        "render vs disc": "",
        "preview s": median_spread(pre)[0],
        "preview / capture": median_spread([e / b for e, b in zip(extra, asked)])[0],
    }


def main_bench(rounds: int, auto: bool, spps: list[int]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        designs = _designs(d)
        areas = {k: read_design(p).open_area_mm2 for k, p in designs.items()}
        off = ["--diffraction", "off"]
        for name, p in designs.items():  # warm-up: each kernel compiled once
            _render(p, d / f"warm_{name}", off)
        rows = []
        for spp in spps:
            times = {k: [] for k in designs}
            for _ in range(rounds):
                for name, p in designs.items():
                    times[name].append(_render(p, d / name, off, spp))
            rows += [_row(name, areas[name], times) for name in designs]
        if auto:
            rows += [_auto_row(name, p, areas[name], d, rounds) for name, p in designs.items()]
    record(
        "Bitmap schedules at disc speed (issue 46, item 4)",
        rows,
        f"train 200x120 window of the 1280x960 sensor, {rounds} interleaved rounds after "
        "a warm-up; 64 patterns in 20 ms at F8; ratios to the disc schedule in the same round. "
        "Before the fix the slit design's 160x120 capture took 188.7 s of render against 2.8 s "
        "for the disc (64 steps x 2 passes, each re-reading the 64 masks). With --auto, "
        "'preview s' is the preview's recorded time (with the process's first render and the "
        "diffraction kernels, which the capture would otherwise take) and 'preview / capture' "
        "is (wall with auto - wall with its decision asked for) / the latter, medians of the "
        "rounds",
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--auto", action="store_true", help="also time diffraction auto's preview")
    ap.add_argument("--spp", type=int, nargs="+", default=[512, 2048])
    a = ap.parse_args()
    main_bench(a.rounds, a.auto, a.spp)
