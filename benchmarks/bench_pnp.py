"""Plug-and-play deconvolution (issue 29 item 1): pnp against BM3D deblurring, hl and Wiener,
side by side, and pnp's PSNR against iterations, penalty scale and seconds.

Captures as in bench_deconvolve.py: the 13 scikit-image photographs, grey, 256 x 256, blurred
by the prototype's discrete 16-pattern coded PSF (s = 0), Gaussian noise sigma = 0.01 (seed
0), every method told that sigma. The methods run one after the other on each image, so a
shared machine slows them alike: compare the seconds as ratios. pnp's network is compiled
(jax) by a warm-up call before any timing. The issue's goal: pnp >= BM3D + 0.3 dB at <= 3x
BM3D's seconds.

    python benchmarks/bench_pnp.py [--variants] [--colour] [--sweep]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from bench_deconvolve import PHOTOS, SIGMA, K, grey_capture, photo, sensor_capture
from common import record

from pacam_render.restore import pnp
from pacam_render.restore.deconvolve import deconvolve
from pacam_render.restore.metrics import psnr

METHODS = ("wiener", "hl", "bm3d", "pnp")


def timed(y, method: str, **kw):
    """deconvolve(y, K, method, **kw) and its seconds."""
    t0 = time.perf_counter()
    out = deconvolve(y, K, method, **kw)
    return out, time.perf_counter() - t0


def side_by_side_rows(capture=grey_capture, rgb: bool = False, names=PHOTOS) -> list[dict]:
    rows, acc = [], []
    y0, white0, _ = capture(photo(names[0], rgb))
    deconvolve(y0, K, "pnp", **white0)  # jax compiles the network for this shape
    for name in names:
        x = photo(name, rgb)
        y, white, _ = capture(x)
        sigma = white["noise_sigma"]
        row: dict = {"photo": name}
        for m in METHODS:
            est, dt = timed(y, m, noise_sigma=sigma)
            row[f"{m} dB"], row[f"{m} s"] = psnr(est, x), dt
        row["pnp - bm3d dB"] = row["pnp dB"] - row["bm3d dB"]
        row["pnp s / bm3d s"] = row["pnp s"] / row["bm3d s"]
        rows.append(row)
        acc.append([row[k] for k in row if k != "photo"])
    mean = np.mean(acc, axis=0)
    rows.append({"photo": "**mean**", **dict(zip(list(rows[0])[1:], mean))})
    return rows


def _mean_runs(xs, ys, **kw) -> tuple[float, float]:
    """Mean PSNR and seconds per image of pnp with ``kw`` over the captures."""
    runs = [timed(y, "pnp", noise_sigma=SIGMA, **kw) for y in ys]
    return np.mean([psnr(e, x) for (e, _), x in zip(runs, xs)]), np.mean([t for _, t in runs])


def iteration_rows(names=PHOTOS[:4]) -> list[dict]:
    """PSNR against iterations (at the default lam) and lam (at the default iterations)."""
    xs = [photo(n, False) for n in names]
    ys = [grey_capture(x)[0] for x in xs]
    rows = []
    runs = [(n, pnp.LAMBDA) for n in (2, 3, 4, 5, 6, 8, 12)]
    runs += [(pnp.ITERATIONS, lam) for lam in (0.2, 0.5, 1.0)]
    for n, lam in runs:
        db, secs = _mean_runs(xs, ys, iterations=n, lam=lam)
        rows.append({"iterations": n, "lam": lam, "mean dB": db, "s per image": secs})
    return rows


SWEEP_PHOTOS = ("camera", "brick", "hubble_deep_field", "rocket", "clock")
"""The camera and the four photographs on which pnp lost most to BM3D before the sweep."""


def sweep_rows(names=SWEEP_PHOTOS) -> list[dict]:
    """One knob at a time from the defaults: the self-ensemble, the schedule's end (in
    multiples of sigma) and the window of the residual's mean (0: not put back)."""
    xs = [photo(n, False) for n in names]
    ys = [grey_capture(x)[0] for x in xs]
    knobs = [("ensemble", n) for n in pnp.ENSEMBLES]
    knobs += [("END_FACTOR", f) for f in (1.0, 2.0, 3.0, 4.0)]
    knobs += [("MEAN_WINDOW_PX", w) for w in (0.0, 2.0, 4.0, 8.0)]
    rows = []
    for knob, value in knobs:
        kw = {"ensemble": value} if knob == "ensemble" else {}
        saved = getattr(pnp, knob, None)
        if knob != "ensemble":
            setattr(pnp, knob, value)
        try:
            db, secs = _mean_runs(xs, ys, **kw)
        finally:
            if knob != "ensemble":
                setattr(pnp, knob, saved)
        rows.append({"knob": knob, "value": value, "mean dB": db, "s per image": secs})
    return rows


def variant_rows(names=PHOTOS[:4]) -> list[dict]:
    """scico's DnCNN variants with a noise-level input: 6 layers against 17, 8 iterations."""
    xs = [photo(n, False) for n in names]
    ys = [grey_capture(x)[0] for x in xs]
    rows, default = [], pnp.VARIANT
    try:
        for variant in ("6N", "17N"):
            pnp.VARIANT = variant
            deconvolve(ys[0], K, "pnp", noise_sigma=SIGMA)  # compile
            runs = [timed(y, "pnp", noise_sigma=SIGMA) for y in ys]
            rows.append(
                {
                    "variant": variant,
                    "mean dB": np.mean([psnr(e, x) for (e, _), x in zip(runs, xs)]),
                    "s per image": np.mean([dt for _, dt in runs]),
                }
            )
    finally:
        pnp.VARIANT = default
    return rows


OPPONENT = np.array([[1, 1, 1], [1, 0, -1], [1, -2, 1]], float)
OPPONENT /= np.linalg.norm(OPPONENT, axis=1, keepdims=True)  # orthonormal: white stays white


OPPONENT_TITLE = "pnp colour: per RGB channel against an opponent space, 4 photographs (issue 29)"
OPPONENT_NOTE = "ICX285 at 300 photons/px/ms as bench_deconvolve's; white sigma at the mean level"


def opponent_rows(names=PHOTOS[:4]) -> list[dict]:
    """Colour per RGB channel (the default) against denoising in an orthonormal opponent space
    (luminance and two chroma planes), on ICX285 captures."""
    per_channel = pnp.self_ensemble

    def opponent(denoise, planes, level, n):
        q = np.einsum("ij,jhw->ihw", OPPONENT, planes)
        return np.einsum("ji,jhw->ihw", OPPONENT, per_channel(denoise, q, level, n))

    rows = []
    for name in names:
        x = photo(name, True)
        y, white, _ = sensor_capture(x)
        row = {"photo": name, "rgb dB": psnr(deconvolve(y, K, "pnp", **white), x)}
        pnp.self_ensemble = opponent
        try:
            row["opponent dB"] = psnr(deconvolve(y, K, "pnp", **white), x)
        finally:
            pnp.self_ensemble = per_channel
        rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", action="store_true", help="also DnCNN 17N (minutes)")
    ap.add_argument("--colour", action="store_true", help="also 4 colour ICX285 captures")
    ap.add_argument("--only", choices=["opponent"], help="only this table")
    ap.add_argument("--sweep", action="store_true", help="also ensemble, end, window (minutes)")
    args = ap.parse_args()
    if args.only == "opponent":
        record(OPPONENT_TITLE, opponent_rows(), OPPONENT_NOTE)
        return
    note = (
        "256x256 grey, prototype coded PSF (s = 0), sigma 0.01, every method told it; "
        "2 cores shared with other jobs: the seconds are side by side, compare ratios"
    )
    record("pnp against BM3D, hl and Wiener, 13 photographs (issue 29)", side_by_side_rows(), note)
    record("pnp: PSNR against iterations and lam, 4 photographs (issue 29)", iteration_rows(), note)
    if args.sweep:
        record(
            "pnp: self-ensemble, schedule end and residual mean, 5 photographs (issue 29)",
            sweep_rows(),
            note + f"; photographs {', '.join(SWEEP_PHOTOS)}; one knob moved at a time",
        )
    if args.variants:
        record("pnp: DnCNN 6N against 17N, 4 photographs (issue 29)", variant_rows(), note)
    if args.colour:
        record(
            "pnp per channel, colour ICX285 at 300 photons/px/ms, 4 photographs (issue 29)",
            side_by_side_rows(sensor_capture, True, PHOTOS[:4]),
            "as bench_deconvolve's colour captures; every method gets the white sigma at the "
            "mean level; pnp restores each channel alone. 2 cores shared: compare ratios",
        )
        record(OPPONENT_TITLE, opponent_rows(), OPPONENT_NOTE)


if __name__ == "__main__":
    main()
