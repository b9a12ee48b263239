"""Diffraction in a capture: in the rays against the post-process, error against run time.

On part of the crossover study's window (the prototype's coded camera on the train set, full
pixel scale), each way of adding the F9.85 opening's diffraction is scored against a
reference, the rays' method at many samples (issue 36, item 1):

- ``geometric``: diffraction left out (what every capture did before);
- ``rays``: each film position jittered by a draw from the Airy pattern
  (:mod:`pacam_render.render.ray_diffraction`): unbiased, with more Monte Carlo noise;
- ``post-process``: the geometric capture convolved with the band kernel, channel by channel
  (:mod:`pacam_render.exposure.optics.diffraction`): no added noise, a bias where the image
  holds detail finer than the pixel grid.

For each: the samples, the seconds, the RMS error to the reference over the window (white =
1, the reference's own Monte Carlo variance removed), its Monte Carlo sigma, and the error per
second 1 / (err^2 t) relative to the rays'. The reference's spp is 16x the largest tried.

    python benchmarks/bench_ray_diffraction.py [--quick] [--spp N ...]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from common import record

from pacam_render.exposure.camera import capture_design, mode_camera
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.optics.diffraction import diffract
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec


def capture(crop, spp: int, diffraction: str, seed: int, grey: bool = False):
    spec = CaptureSpec.geometric(
        scene="train", mode="coded", width=1280, height=960, crop=crop, spp=spp,
        seed=seed, diffraction=diffraction, grey=grey,
    )  # fmt: skip
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = render_capture(spec, progress=False, truth=False)
    return spec, cap, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a smaller window, fewer samples")
    ap.add_argument("--spp", type=int, nargs="+", help="the samples tried (default 128 512)")
    ap.add_argument("--grey", action="store_true", help="one channel at 550 nm (llvm_ad_mono)")
    args = ap.parse_args()
    crop = (360, 600, 96, 64) if args.quick else (320, 580, 160, 96)
    spps = tuple(args.spp) if args.spp else ((64, 256) if args.quick else (128, 512))
    spec, ref, ref_s = capture(crop, 16 * spps[-1], "on", seed=99, grey=args.grey)
    lf = ref.record.light_factor
    ref_var = float(np.mean(ref.mc_sigma**2))
    cam, _ = mode_camera(capture_design(spec), "coded")
    rows = []
    for spp in spps:
        for method in ("geometric", "rays", "post-process"):
            on = "on" if method == "rays" else "off"
            s, cap, sec = capture(crop, spp, on, seed=spp, grey=args.grey)
            img, var = cap.image, cap.mc_sigma**2
            if method == "post-process":
                t0 = time.perf_counter()
                d = diffract(img, {}, var, cam, "coded", plan_capture(s).pitch_mm)
                img, var, sec = d.image, d.variance, sec + time.perf_counter() - t0
            err2 = max(float(np.mean((img - ref.image) ** 2)) - ref_var, 0.0)
            rows.append(
                {
                    "window": f"{crop[2]}x{crop[3]} at ({crop[0]}, {crop[1]})"
                    + (", grey" if args.grey else ""),
                    "method": method,
                    "spp": cap.record.effective_spp,
                    "seconds": sec,
                    "RMS error (white)": np.sqrt(err2) / lf,
                    "MC sigma (white)": np.sqrt(float(np.mean(var))) / lf,
                    "1/(err^2 t)": 1.0 / max(err2 / lf**2 * sec, 1e-300),
                }
            )
    for spp in sorted({r["spp"] for r in rows}):
        rays = next(r for r in rows if r["spp"] == spp and r["method"] == "rays")
        for r in rows:
            if r["spp"] == spp:
                r["vs rays"] = r["1/(err^2 t)"] / rays["1/(err^2 t)"]
    notes = (
        f"reference: rays at {ref.record.effective_spp} spp ({ref_s:.0f} s), its MC variance "
        f"removed from each error; the prototype's coded camera on the train set at full pixel "
        f"scale (F9.85 opening, lambda N = 0.93/0.84/0.71 px in R/G/B, grey 0.84 at 550 nm); "
        f"RMS over the window "
        f"and the channels, white = 1 (light factor {lf:.4g}); seconds include the "
        "post-process's FFTs"
    )
    record("Diffraction in a capture: rays against the post-process (issue 36)", rows, notes)


if __name__ == "__main__":
    main()
