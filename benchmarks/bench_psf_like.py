"""``pacam psf --like``: the kernel of each capture's own camera against its ray-traced PSF.

Three captures of the train window, each made with a camera other than the prototype: a
``--cover 1.4`` design (r 3.13 px), an 8-pattern designed schedule (``--schedule``, every
second opening of the parabola, 0.7x as wide), and a design file of 8 LCoS bitmaps (square
openings along the parabola, so that its kernel is not a disc's). For each,
``pacam psf --like CAPTURE --render`` is run with two seeds: the figures of ``psf.json`` are
compared with the capture's, and the L1 of the two renders' mean to the analytic kernel with
the Monte Carlo floor L1(A, B) / 2 (the expected L1 of that mean if the renderer and the model
agree; ``validate_psf``'s estimator). The prototype's kernel, which ``--like`` wrote for every
capture before issue 35, is scored the same way.

    python benchmarks/bench_psf_like.py [--spp N]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from common import record

from pacam_render.cli import main as pacam
from pacam_render.io.exr import read_layer
from pacam_render.model.camera import preset
from pacam_render.model.design_file import write_design
from pacam_render.model.masks import MaskStack, square_masks
from pacam_render.psf.analytic import design_psf
from pacam_render.restore.metrics import rel_l1

CROP = "540,430,96,64"


def _inputs(root: Path) -> dict[str, list[str]]:
    """The three cameras, as render flags."""
    proto = preset("prototype")
    centres = proto.pattern_centres_xy_mm()[::2]
    (root / "schedule.json").write_text(json.dumps({  # a narrower parabola: its own a_i
        "n_patterns": 8, "centres_mm": (0.7 * centres).tolist(), "radius_mm": proto.R_mm,
        "focus_distance_mm": proto.focus_distance_mm,
    }))  # fmt: skip
    stack = MaskStack(
        square_masks(centres, 0.5 * np.sqrt(np.pi) * proto.R_mm)
    )  # squares of the disc's area
    cam = proto.with_(pattern_masks=stack, n_patterns=8, R_mm=stack.equivalent_radius_mm())
    write_design(root / "squares.toml", cam.with_(name="8 squares"))
    return {
        "cover 1.4": ["--cover", "1.4"],
        "8-pattern schedule": ["--schedule", str(root / "schedule.json")],
        "design file of 8 bitmaps": ["--design", str(root / "squares.toml")],
    }


def _row(root: Path, name: str, flags: list[str], spp: int) -> dict:
    cap = root / name.replace(" ", "_")
    args = ["render", "train", "--crop", CROP, "--spp", "4", "--quiet", "--out", str(cap)]
    assert pacam([*args, *flags]) == 0
    optics = json.loads((cap / "capture.json").read_text())["optics"]
    kernels, seconds = [], 0.0
    for seed in (0, 1):
        out = cap / f"psf{seed}"
        t0 = time.perf_counter()
        like = ["psf", "--like", str(cap / "capture.exr"), "--velocity", "0", "--render"]
        assert (
            pacam([*like, "--spp", str(spp), "--seed", str(seed), "--quiet", "--out", str(out)])
            == 0
        )
        seconds += time.perf_counter() - t0
        kernels.append(read_layer(out / "psf_rendered.exr", "psf").astype(np.float64))
    psf = json.loads((cap / "psf0" / "psf.json").read_text())
    model = read_layer(cap / "psf0" / "psf_analytic.exr", "psf").astype(np.float64)
    mean = 0.5 * (kernels[0] + kernels[1])
    floor = rel_l1(kernels[0], kernels[1]) / 2.0
    same = all(psf[k] == optics[k] for k in ("r_px", "a_i_px_per_ms2", "n_patterns"))
    proto = design_psf(preset("prototype"), "coded", 0.0, size=model.shape, origin="pinhole")
    return {
        "capture": name,
        "r px (capture / psf.json)": f"{optics['r_px']:.4g} / {psf['r_px']:.4g}",
        "a_i (capture / psf.json)": f"{optics['a_i_px_per_ms2']:.4g} / {psf['a_i_px_per_ms2']:.4g}",
        "patterns": f"{optics['n_patterns']} / {psf['n_patterns']}",
        "figures equal": same,
        "L1 mean vs --like kernel": rel_l1(mean, model),
        "MC floor": floor,
        "L1 / floor": rel_l1(mean, model) / floor,
        "L1 mean vs prototype's kernel": rel_l1(mean, proto),
        "render s (2 seeds)": seconds,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=2048, help="per film pixel per window (2048)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        rows = [_row(root, n, f, args.spp) for n, f in _inputs(root).items()]
    notes = (
        f"train window {CROP}, captures at 4 spp (only their records are used); each kernel "
        f"rendered twice (ptracer, seeds 0 and 1, {args.spp} spp per window); floor = L1(A, B) "
        "/ 2; 'prototype's kernel': what psf --like wrote for every capture before issue 35"
    )
    record("psf --like: each capture's own kernel against its rendered PSF (issue 35)", rows,
           notes)  # fmt: skip


if __name__ == "__main__":
    main()
