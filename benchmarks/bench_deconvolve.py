"""Deconvolution benchmark (issue 6): our Wiener vs skimage.restoration.wiener speed ratio, and
PSNR / SSIM against run time for every method on the same synthetic coded capture.

The capture: a scikit-image photograph, blurred with the prototype's discrete coded PSF (s = 0)
by linear convolution of the reflect-extended scene, plus Gaussian noise sigma = 0.01.

    python benchmarks/bench_deconvolve.py [--full]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from common import median_spread, record, timeit
from scipy.signal import fftconvolve
from skimage import color, data, transform
from skimage.metrics import structural_similarity
from skimage.restoration import wiener as sk_wiener

from pacam_render import prototype
from pacam_render.psf.analytic import design_psf
from pacam_render.restore import deconvolve as D
from pacam_render.restore import metrics

SIGMA = 0.01


def capture(shape: tuple[int, int], k: np.ndarray, seed: int = 0):
    x = transform.resize(color.rgb2gray(data.astronaut()), shape, anti_aliasing=True)
    pad = k.shape[0]
    y = fftconvolve(np.pad(x, pad, mode="reflect"), k, mode="same")[pad:-pad, pad:-pad]
    return x, y + np.random.default_rng(seed).normal(0, SIGMA, y.shape)


def speed_rows(k: np.ndarray, repeat: int) -> list[dict]:
    rows = []
    for shape in [(512, 512), (960, 1280)]:
        _, y = capture(shape, k)
        ours = median_spread(timeit(lambda y=y: D.wiener(y, k, nsr=1e-2), repeat))
        prior = median_spread(timeit(lambda y=y: D.wiener(y, k, noise_sigma=SIGMA), repeat))
        theirs = median_spread(timeit(lambda y=y: sk_wiener(y, k, 1e-2, clip=False), repeat))
        rows.append(
            {
                "image": f"{shape[1]}x{shape[0]}",
                "ours_const_ms": 1e3 * ours[0],
                "ours_prior_ms": 1e3 * prior[0],
                "skimage_ms": 1e3 * theirs[0],
                "ratio_ours/skimage": ours[0] / theirs[0],
                "ratio_spread": (ours[0] + ours[1]) / max(theirs[0] - theirs[1], 1e-9)
                - ours[0] / theirs[0],
            }
        )
    return rows


def quality_rows(k: np.ndarray, shape: tuple[int, int]) -> list[dict]:
    x, y = capture(shape, k)
    runs = {
        "none (blurred input)": lambda: y,
        "wiener (1/f^2 prior)": lambda: D.wiener(y, k, noise_sigma=SIGMA),
        "wiener (oracle scale)": lambda: D.oracle_wiener(y, k, x, SIGMA)[0],
        "skimage wiener b=1e-2": lambda: sk_wiener(y, k, 1e-2, clip=False),
        "richardson-lucy 10 it": lambda: D.richardson_lucy(np.clip(y, 0, None), k, 10),
        "richardson-lucy 30 it": lambda: D.richardson_lucy(np.clip(y, 0, None), k, 30),
        "unsupervised wiener": lambda: D.unsupervised_wiener(y, k),
    }
    try:
        import bm3d  # noqa: F401

        runs["bm3d deblurring"] = lambda: D.bm3d_deblur(y, k, SIGMA)
    except ImportError:
        pass
    rows = []
    for name, fn in runs.items():
        t0 = time.perf_counter()
        est = fn()
        dt = time.perf_counter() - t0
        rows.append(
            {
                "method": name,
                "time_s": dt,
                "psnr_db": metrics.psnr(est, x),
                "ssim": structural_similarity(np.clip(est, 0, 1), x, data_range=1.0),
            }
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="1280x960 quality run, more repeats")
    args = ap.parse_args()
    k = design_psf(prototype(), "coded", 0.0)
    record(
        "Deconvolution speed: pacam Wiener vs skimage.restoration.wiener (issue 6)",
        speed_rows(k, 9 if args.full else 5),
        notes=f"grey float64, PSF {k.shape[0]}x{k.shape[1]} (prototype coded, s=0); ours pads "
        "by the PSF size and tapers, skimage wraps around; median of repeats",
    )
    shape = (960, 1280) if args.full else (256, 256)
    record(
        f"Deconvolution quality vs run time, {shape[1]}x{shape[0]} astronaut (issue 6)",
        quality_rows(k, shape),
        notes=f"prototype coded PSF at s=0, Gaussian noise sigma={SIGMA}; PSNR/SSIM vs sharp image",
    )


if __name__ == "__main__":
    main()
