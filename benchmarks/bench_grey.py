"""Grey experiments: Monte Carlo error per second of the mono variant against RGB (issue 35,
item 5).

The same coded capture of the train (a window of the full-resolution sensor, the prototype's
own pixel scale) is rendered with ``llvm_ad_rgb`` and with ``llvm_ad_mono`` (``grey=True``) at
the same spp, with two seeds each, ``--rounds`` times, interleaved (rgb, mono, rgb, mono, ...)
after one untimed warm-up capture of each (kernel compilation). For each variant the table
gives the effective spp, the capture's own seconds (``render_error.seconds``: the minimum over
the rounds and seeds, the least disturbed by other work, and the median), the Monte Carlo
sigma the capture states (``render_error.mc_sigma``: RMS over the window, and over R, G, B for
the colour one), and the sigma of the grey image measured from the two seeds, RMS(g0 - g1) /
sqrt(2), where g is the mono capture or the luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of the
colour one (what mono renders: Mitsuba's mono variant takes the luminance of every RGB
reflectance and emitter). Efficiency is 1 / (sigma^2 t); the ratio is each row's over the
colour capture's, with the stated sigma and with the grey sigma (the fair comparison for an
experiment that needs only grey).

    python benchmarks/bench_grey.py [--spp 256,1024] [--crop 200,560,200,120] [--rounds 2]
"""

from __future__ import annotations

import argparse
import statistics
import warnings

import numpy as np
from common import record

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec, parse_crop
from pacam_render.limits import PacamWarning

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance weights (Mitsuba's ``luminance()`` of linear sRGB)."""
VARIANTS = {"llvm_ad_rgb": False, "llvm_ad_mono": True}
"""The variants compared, and the ``grey`` of their captures."""


def capture(spp: int, crop, grey: bool, seed: int):
    """One coded capture of the train, no ground truth, notes silenced."""
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=1280, height=960, crop=crop,
                                 spp=spp, seed=seed, grey=grey)  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)
        return render_capture(spec, progress=False, truth=False)


def grey_image(image: np.ndarray) -> np.ndarray:
    """The capture's grey image: itself when grey, its luminance when colour."""
    return image if image.ndim == 2 else image @ LUMINANCE


def measure(spp: int, crop, rounds: int) -> list[dict]:
    """Both variants at ``spp``: seeds 0 and 1, ``rounds`` times each, interleaved."""
    caps: dict[str, dict[int, object]] = {v: {} for v in VARIANTS}
    times: dict[str, list[float]] = {v: [] for v in VARIANTS}
    for _ in range(rounds):
        for seed in (0, 1):
            for name, grey in VARIANTS.items():
                cap = capture(spp, crop, grey, seed)
                assert cap.record.variant == name, (cap.record.variant, name)
                caps[name][seed] = cap  # the same seed renders the same image every round
                times[name].append(cap.record.render_error.seconds)
    rows = []
    for name, pair in caps.items():
        a, b = pair[0], pair[1]
        err = [c.record.render_error for c in (a, b)]
        seconds = min(times[name])  # the least disturbed by other work on the machine
        stated = float(np.sqrt(np.mean([e.mc_sigma**2 for e in err])))
        diff = grey_image(a.image) - grey_image(b.image)
        measured = float(np.sqrt(np.mean(diff**2) / 2.0))
        rows.append({
            "variant": name,
            "channels": "Y" if a.image.ndim == 2 else "RGB (Y for the grey sigma)",
            "spp": err[0].spp,
            "seconds (min)": seconds,
            "seconds (median)": statistics.median(times[name]),
            "MC sigma (capture.json)": stated,
            "grey MC sigma (2 seeds)": measured,
            "1/(sigma^2 t) stated": 1.0 / (stated**2 * seconds),
            "1/(sigma^2 t) grey": 1.0 / (measured**2 * seconds),
        })  # fmt: skip
    base = rows[0]
    for r in rows:
        r["ratio stated"] = r["1/(sigma^2 t) stated"] / base["1/(sigma^2 t) stated"]
        r["ratio grey"] = r["1/(sigma^2 t) grey"] / base["1/(sigma^2 t) grey"]
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", default="256,1024", help="comma-separated spp (default 256,1024)")
    ap.add_argument("--crop", default="200,560,200,120", help="X,Y,W,H of the 1280x960 sensor")
    ap.add_argument("--rounds", type=int, default=2, help="timed renders per seed (default 2)")
    args = ap.parse_args()
    crop = parse_crop(args.crop)
    spps = [int(s) for s in args.spp.split(",")]
    for grey in VARIANTS.values():  # warm-up: compile every kernel once, untimed
        capture(spps[0], crop, grey, 99)
    rows = [r for spp in spps for r in measure(spp, crop, args.rounds)]
    record(
        "Grey experiments: mono vs RGB variant, error per second (issue 35 item 5)",
        rows,
        notes=f"train, coded, {crop[2]}x{crop[3]} window at ({crop[0]}, {crop[1]}) of the "
        "1280x960 sensor, ldsampler, 2 passes, no ground truth; seconds: the capture's own "
        f"(render_error.seconds), min and median of {2 * args.rounds} captures (seeds 0 and 1, "
        f"{args.rounds} rounds, the variants interleaved), the min used; grey MC sigma: "
        "RMS(g0 - g1) / sqrt(2) of the two seeds' grey images (the mono capture, or the "
        "colour capture's luminance Y); ratio: efficiency over llvm_ad_rgb's at the same spp; "
        "the machine line names the variant active last, both ran (see the table)",
    )


if __name__ == "__main__":
    main()
