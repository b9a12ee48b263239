"""Sparse-prior deconvolution (issue 16): PSNR against run time for Wiener, hyper-Laplacian and
TV, and each sparse method's PSNR against its data weight (how LAMBDA_SCALE was chosen).

The captures: scikit-image photographs in grey, 256 x 256, blurred with the prototype's
discrete coded PSF (s = 0) by linear convolution of the reflect-extended scene, plus Gaussian
noise of sigma 0.01 and 0.03; every method gets the true sigma. Run time is the median of 3
runs, measured in the same process for every method.

    python benchmarks/bench_sparse.py
"""

from __future__ import annotations

import statistics
import time

import numpy as np
from common import record
from scipy.signal import fftconvolve
from skimage import color, data, transform

from pacam_render import prototype
from pacam_render.psf.analytic import design_psf
from pacam_render.restore import sparse
from pacam_render.restore.deconvolve import deconvolve
from pacam_render.restore.metrics import psnr

IMAGES = ("astronaut", "camera", "coffee", "chelsea")
SIGMAS = (0.01, 0.03)


def photo(name: str) -> np.ndarray:
    x = getattr(data, name)()
    x = color.rgb2gray(x) if x.ndim == 3 else x / 255.0
    return transform.resize(x, (256, 256), anti_aliasing=True)


def blurred(x: np.ndarray, k: np.ndarray, sigma: float) -> np.ndarray:
    pad = k.shape[0]
    y = fftconvolve(np.pad(x, pad, mode="reflect"), k, mode="same")[pad:-pad, pad:-pad]
    return y + np.random.default_rng(0).normal(0, sigma, y.shape)


def timed(fn, repeat: int = 3):
    out, times = None, []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def method_rows(k: np.ndarray) -> list[dict]:
    rows = []
    for sigma in SIGMAS:
        for method in ("wiener", "hl", "tv"):
            gains, secs = [], []
            for name in IMAGES:
                x = photo(name)
                y = blurred(x, k, sigma)
                est, s = timed(lambda y=y, m=method, s=sigma: deconvolve(y, k, m, noise_sigma=s))
                gains.append(psnr(est, x))
                secs.append(s)
            rows.append(
                {
                    "sigma": sigma,
                    "method": method,
                    **{f"{n} dB": g for n, g in zip(IMAGES, gains)},
                    "mean dB": float(np.mean(gains)),
                    "ms per 256^2": 1e3 * float(np.median(secs)),
                }
            )
    return rows


def weight_rows(k: np.ndarray) -> list[dict]:
    rows, saved = [], dict(sparse.LAMBDA_SCALE)
    try:
        for method in ("hl", "tv"):
            for scale in (0.03, 0.1, 0.2, 0.3, 0.6, 1.0):
                sparse.LAMBDA_SCALE[method] = scale
                row = {"method": method, "lambda sigma^2": scale}
                for sigma in SIGMAS:
                    vals = [
                        psnr(deconvolve(blurred(x, k, sigma), k, method, noise_sigma=sigma), x)
                        for x in map(photo, IMAGES)
                    ]
                    row[f"mean dB at sigma {sigma}"] = float(np.mean(vals))
                rows.append(row)
    finally:
        sparse.LAMBDA_SCALE.update(saved)
    return rows


def main() -> None:
    k = design_psf(prototype(), "coded", 0.0)
    record(
        "Sparse priors vs Wiener: PSNR and run time (issue 16)",
        method_rows(k),
        notes="prototype coded PSF (s = 0, 25x25 px), 4 scikit-image photographs at 256x256 in "
        "grey, Gaussian noise, the true sigma given to every method",
    )
    record(
        "Sparse priors: PSNR against the data weight lambda sigma^2 (issue 16)",
        weight_rows(k),
        notes=f"defaults: {sparse.LAMBDA_SCALE}; same captures",
    )


if __name__ == "__main__":
    main()
