"""The classical gap (issue 29 item 2): where hl and tv lose to BM3D on Gaussian noise.

Captures as in bench_deconvolve.py: the 13 scikit-image photographs, grey, 256 x 256, blurred
by the prototype's 16-pattern coded PSF (s = 0), Gaussian noise sigma = 0.01 (seed 0), every
method told sigma. BM3D and Wiener are not re-run: their per-photo PSNR is the last "pnp
against BM3D, hl and Wiener, 13 photographs (issue 29)" table of RESULTS.md (BM3D 9-23 s per
image there, 14.5 s on average). Knobs: the data weight lambda sigma^2 and hl's alpha, the
solver's beta schedule (last beta, iterations), the boundary pad, diagonal first differences and
second differences in the prior (a solver of this script's own: uniform weights, grey; its
plain run is checked against the library's in the same table), and a per-image weight by SURE
(``lambda_scale="sure"``). The library's changes are checked on colour ICX285 captures too. One
core: run with OMP_NUM_THREADS=1; the seconds are on a machine shared with other jobs.

    cd benchmarks && OMP_NUM_THREADS=1 python bench_classical_gap.py [--only TABLE ...]
"""

from __future__ import annotations

import argparse
import math
import time
from contextlib import contextmanager

import numpy as np
import scipy.fft as sfft
from bench_deconvolve import PHOTOS, SIGMA, K, blur, grey_capture, photo, sensor_capture
from common import record

from pacam_render.restore import sparse
from pacam_render.restore.fourier import pad_width, psf_to_otf, taper_pad
from pacam_render.restore.metrics import psnr
from pacam_render.restore.splitting import BETA_START, shrink

BM3D_DB = (28.12, 32.69, 30.32, 32.3, 46.84, 28.91, 28.03, 23.16, 24.46, 28.96, 37.68, 34.36, 32.27)
WIENER_DB = (26.95, 28.2, 28.16, 31.8, 41.12, 27.92, 26.82, 23.33, 24.5, 28.13, 36.51, 33.03, 31.18)
HL_OLD_DB = (
    27.91,
    28.8,
    29.45,
    31.91,
    43.13,
    28.52,
    28.05,
    22.66,
    23.86,
    28.34,
    37.65,
    34.98,
    31.73,
)
"""Per photo, in PHOTOS' order, from RESULTS.md (2026-11-25 06:30 UTC, bench_pnp.py)."""
BM3D_S = 14.52
"""BM3D's mean seconds per image in that table (2 shared cores)."""
OLD_SCHEDULE = {"hl": (256.0, 6), "tv": (256.0, 6)}
"""Krishnan & Fergus' schedule, the default before this study."""


@contextmanager
def patched(table: dict, **values):
    """Set entries of a module-level dict for the duration of a block."""
    saved = dict(table)
    table.update(values)
    try:
        yield
    finally:
        table.clear()
        table.update(saved)


def captures(names=PHOTOS) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for name in names:
        x = photo(name, False)
        out.append((x, grey_capture(x)[0]))
    return out


def score(caps, fn) -> tuple[np.ndarray, float]:
    """PSNR of fn(y) per capture, and the mean seconds per image."""
    t0 = time.perf_counter()
    got = np.array([psnr(fn(y), x) for x, y in caps])
    return got, (time.perf_counter() - t0) / len(caps)


def summary(got: np.ndarray, seconds: float) -> dict:
    cam = PHOTOS.index("camera")
    return {
        "mean dB": float(got.mean()),
        "mean - bm3d dB": float(got.mean() - np.mean(BM3D_DB)),
        "camera dB": float(got[cam]),
        "camera - bm3d dB": float(got[cam] - BM3D_DB[cam]),
        "s per image": seconds,
    }


def lambda_alpha_rows(caps) -> list[dict]:
    rows = []
    for method, alphas, lams in (
        ("hl", (0.5, 0.6, 2 / 3, 0.8), (0.2, 0.3, 0.4, 0.5)),
        ("tv", (1.0,), (0.1, 0.15, 0.2, 0.3)),
    ):
        for alpha in alphas:
            for lam in lams:
                a = None if method == "tv" else alpha

                def fn(y, method=method, a=a, lam=lam):
                    return sparse.sparse_deconvolve(y, K, method, SIGMA, a, lambda_scale=lam)

                row = {"method": method, "alpha": alpha, "lambda sigma^2": lam}
                rows.append(row | summary(*score(caps, fn)))
    return rows


def schedule_rows(caps) -> list[dict]:
    rows = []
    for method in ("hl", "tv"):
        for stop, n in ((256, 6), (256, 12), (1024, 6), (1024, 12), (4096, 8), (4096, 12)):
            with patched(sparse.SCHEDULE, **{method: (float(stop), n)}):
                got = score(caps, lambda y, m=method: sparse.sparse_deconvolve(y, K, m, SIGMA))
            ratio = (stop / BETA_START) ** (1.0 / (n - 1))
            row = {"method": method, "last beta": stop, "iterations": n, "beta step": ratio}
            rows.append(row | summary(*got))
    return rows


def prior_filters(diagonal: float, second: float) -> tuple[list[np.ndarray], list[float]]:
    """The prior's filters and weights: d_x and d_y (1); the two diagonal first differences
    (``diagonal``); d_xx, d_yy (``second``) and d_xy (sqrt(2) ``second``, so the three sum to
    the Hessian's Frobenius norm when alpha = 2)."""
    dx = np.array([[0.0, -1.0, 1.0]])
    filters, weights = [dx, dx.T], [1.0, 1.0]
    if diagonal > 0:
        diag = np.zeros((3, 3))
        diag[1, 1], diag[2, 2] = -1.0, 1.0
        filters += [diag, np.fliplr(diag)]
        weights += [diagonal, diagonal]
    if second > 0:
        dxx = np.array([[1.0, -2.0, 1.0]])
        dxy = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, -1.0], [0.0, -1.0, 1.0]])
        filters += [dxx, dxx.T, dxy]
        weights += [second, second, math.sqrt(2.0) * second]
    return filters, weights


def hqs(y, lam, alpha, schedule, pad=None, diagonal=0.0, second=0.0) -> np.ndarray:
    """Half-quadratic splitting, grey, uniform weight lam / sigma^2: the library's solver
    (white noise, the same scaling and taper), with the pad's width a parameter and optionally
    more filters in the prior (:func:`prior_filters`): E = w / 2 ||k * x - y||^2 +
    sum_f c_f sum_i |(d_f * x)_i|^alpha."""
    scale = float(np.percentile(np.abs(y), 99.5))
    yp, keep = taper_pad(y / scale, pad_width(K.shape) if pad is None else (pad, pad))
    shape = yp.shape
    filters, weights = prior_filters(diagonal, second)
    D = [psf_to_otf(f, shape) for f in filters]
    otf = psf_to_otf(K, shape)
    w = lam / (SIGMA / scale) ** 2
    h2 = (otf * otf.conj()).real
    d2 = sum(c * (d * d.conj()).real for c, d in zip(weights, D))
    hy = w * otf.conj() * sfft.rfft2(yp)
    X = sfft.rfft2(yp)
    for beta in np.geomspace(BETA_START, *schedule):
        num = hy.copy()
        for c, d in zip(weights, D):
            g = shrink(sfft.irfft2(d * X, s=shape), alpha, beta)
            num += beta * c * d.conj() * sfft.rfft2(g)
        X = num / (w * h2 + beta * d2)
    return scale * sfft.irfft2(X, s=shape)[keep]


def structure_rows(caps) -> list[dict]:
    """The pad's width, diagonal and second differences, on this script's solver."""
    rows = []
    for method, alpha in (("hl", 2 / 3), ("tv", 1.0)):
        lam0, sched = sparse.LAMBDA_SCALE[method], sparse.SCHEDULE[method]
        lib = score(caps, lambda y, m=method: sparse.sparse_deconvolve(y, K, m, SIGMA))
        row = {"method": method, "pad px": 25, "diagonal": 0.0, "second": 0.0}
        rows.append(row | {"lambda sigma^2": lam0, "solver": "library"} | summary(*lib))
        lams = (0.3, 0.4, 0.5) if method == "hl" else (0.2, 0.25, 0.3)
        configs = [(p, 0.0, 0.0, lam0) for p in (13, 25, 50)]
        configs += [(25, d, 0.0, lam) for d in (0.35, 0.5, 1 / math.sqrt(2)) for lam in lams]
        configs += [(25, 0.0, s, lam) for s in (0.1, 0.25) for lam in lams]
        for pad, diag, second, lam in configs:
            got = score(caps, lambda y, c=(lam, alpha, sched, pad, diag, second): hqs(y, *c))
            row = {"method": method, "pad px": pad, "diagonal": diag, "second": second}
            rows.append(row | {"lambda sigma^2": lam, "solver": "script"} | summary(*got))
    for second in (0.0, 0.1, 0.25):
        row = {"method": "hl", "pad px": 25, "diagonal": 0.0, "second": second}
        rows.append(
            row
            | {"lambda sigma^2": "best per image (11)", "solver": "script"}
            | oracle(caps, second)
        )
    return rows


def oracle(caps, second: float) -> dict:
    """hl with the best of 11 weights per image (0.1 to 0.9), on this script's solver."""
    grid = []
    for lam in sparse.LAMBDA_SCALE["hl"] * np.geomspace(1 / 3, 3, 11):
        fn = lambda y, lam=lam: hqs(y, lam, 2 / 3, sparse.SCHEDULE["hl"], second=second)  # noqa: E731
        grid.append(score(caps, fn)[0])
    return summary(np.max(grid, axis=0), float("nan"))


def raw_sure_lambdas(caps, method: str) -> tuple[list[float], float]:
    """The weight of least estimated risk per capture (SURE_SHRINK = 1), and the seconds per
    image of lambda_scale="sure"."""
    raw, spy, shrink0 = [], sparse.sure_lambda, sparse.SURE_SHRINK

    def capture(*args):
        raw.append(spy(*args))
        return raw[-1]

    sparse.sure_lambda, sparse.SURE_SHRINK = capture, 1.0
    try:
        _, seconds = score(
            caps, lambda y: sparse.sparse_deconvolve(y, K, method, SIGMA, lambda_scale="sure")
        )
    finally:
        sparse.sure_lambda, sparse.SURE_SHRINK = spy, shrink0
    return raw, seconds


def sure_rows(caps) -> list[dict]:
    """lambda by SURE per image, times factors; and the per-image oracle on a grid."""
    rows = []
    for method in ("hl", "tv"):
        raw, seconds = raw_sure_lambdas(caps, method)
        for factor in (0.6, 0.7, 0.8, 0.9, 1.0):
            got = np.array(
                [
                    psnr(sparse.sparse_deconvolve(y, K, method, SIGMA, lambda_scale=factor * r), x)
                    for (x, y), r in zip(caps, raw)
                ]
            )
            rows.append({"method": method, "weight": f"sure x {factor:g}"} | summary(got, seconds))
        grid = []
        for lam in sparse.LAMBDA_SCALE[method] * np.geomspace(1 / 3, 3, 11):
            fn = lambda y, m=method, lam=lam: sparse.sparse_deconvolve(  # noqa: E731
                y, K, m, SIGMA, lambda_scale=lam
            )
            grid.append(score(caps, fn)[0])
        best = np.max(grid, axis=0)
        row = {"method": method, "weight": "oracle per image (11 on a grid)"}
        rows.append(row | summary(best, float("nan")))
    return rows


def per_photo_rows(caps) -> list[dict]:
    """The library's hl and tv, default weight and by SURE, against BM3D, photo by photo."""
    runs = {
        "hl": lambda y: sparse.sparse_deconvolve(y, K, "hl", SIGMA),
        "hl sure": lambda y: sparse.sparse_deconvolve(y, K, "hl", SIGMA, lambda_scale="sure"),
        "tv sure": lambda y: sparse.sparse_deconvolve(y, K, "tv", SIGMA, lambda_scale="sure"),
    }
    got = {label: [] for label in runs}
    for x, y in caps:
        for label, fn in runs.items():
            t0 = time.perf_counter()
            db = psnr(fn(y), x)
            got[label].append((db, time.perf_counter() - t0))
    rows = []
    for i, name in enumerate([*PHOTOS, "**mean**"]):
        pick = (lambda v, i=i: v[i]) if i < len(PHOTOS) else (lambda v: np.mean(v, axis=0))
        row = {"photo": name, "wiener dB": pick(np.array(WIENER_DB))}
        row |= {"bm3d dB": pick(np.array(BM3D_DB)), "hl before dB": pick(np.array(HL_OLD_DB))}
        for label, v in got.items():
            db, s = pick(np.array(v))
            row |= {f"{label} dB": float(db), f"{label} s": float(s)}
        row["hl sure - bm3d dB"] = row["hl sure dB"] - row["bm3d dB"]
        row["tv sure - bm3d dB"] = row["tv sure dB"] - row["bm3d dB"]
        rows.append(row)
    return rows


def sigma_rows(caps) -> list[dict]:
    """SURE's weight (its factor chosen at sigma 0.01) at other noise levels, against the fixed
    lambda sigma^2: whether the choice carries over."""
    rows = []
    for sigma in (0.005, 0.02):
        noisy = [(x, blur(x) + np.random.default_rng(0).normal(0, sigma, x.shape)) for x, _ in caps]
        for method in ("hl", "tv"):
            for lam in (None, "sure"):
                fn = lambda y, m=method, lam=lam, s=sigma: sparse.sparse_deconvolve(  # noqa: E731
                    y, K, m, s, lambda_scale=lam
                )
                got, seconds = score(noisy, fn)
                cam = PHOTOS.index("camera")
                rows.append(
                    {"sigma": sigma, "method": method, "weight": lam or "default"}
                    | {"mean dB": float(got.mean()), "camera dB": float(got[cam])}
                    | {"s per image": seconds}
                )
    return rows


def colour_rows(names) -> list[dict]:
    """The schedule's change and SURE on colour ICX285 captures (the sensor's noise model)."""
    caps = []
    for name in names:
        x = photo(name, True)
        y, _, own = sensor_capture(x)
        caps.append((x, y, own))
    rows = []
    for method in ("hl", "tv"):
        for label, schedule, lam in (
            ("before (256, 6)", OLD_SCHEDULE[method], None),
            (f"default {sparse.SCHEDULE[method]}", sparse.SCHEDULE[method], None),
            ("default, sure", sparse.SCHEDULE[method], "sure"),
        ):
            with patched(sparse.SCHEDULE, **{method: schedule}):
                t0 = time.perf_counter()
                got = [
                    psnr(sparse.sparse_deconvolve(y, K, method, lambda_scale=lam, **own), x)
                    for x, y, own in caps
                ]
                s = (time.perf_counter() - t0) / len(caps)
            row = {"method": method, "run": label}
            row |= {f"{n} dB": g for n, g in zip(names, got)}
            rows.append(row | {"mean dB": float(np.mean(got)), "s per image": s})
    return rows


COLOUR_PHOTOS = ("astronaut", "camera", "coffee", "chelsea", "rocket", "coins")
SECTIONS = {
    "lambda": ("hl/tv against lambda and alpha", lambda_alpha_rows, "the schedule of SCHEDULE"),
    "schedule": (
        "hl/tv against the beta schedule",
        schedule_rows,
        "beta from 1 to the last beta in geometric steps; lambda_scale the default",
    ),
    "structure": (
        "the pad, diagonal and second differences",
        structure_rows,
        "solver script: this benchmark's own (uniform weight, grey); library: sparse_deconvolve",
    ),
    "sure": (
        "a per-image weight by SURE",
        sure_rows,
        "lambda = factor x the weight of least SURE; seconds: lambda_scale='sure'",
    ),
    "sigma": (
        "SURE's weight at other noise levels",
        sigma_rows,
        "captures as above at sigma 0.005 and 0.02 (seed 0); default: LAMBDA_SCALE",
    ),
    "photos": (
        "hl/tv against BM3D and Wiener per photo",
        per_photo_rows,
        f"BM3D, Wiener and 'hl before' from RESULTS.md; BM3D {BM3D_S} s per image there",
    ),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", choices=[*SECTIONS, "colour"], help="these tables")
    args = ap.parse_args()
    caps = captures()
    note = f"13 grey photographs, sigma {SIGMA}; BM3D {np.mean(BM3D_DB):.2f} dB (RESULTS.md)"
    for key, (title, rows, notes) in SECTIONS.items():
        if args.only is None or key in args.only:
            record(f"Classical gap: {title} (issue 29)", rows(caps), notes=f"{note}; {notes}")
    if args.only is None or "colour" in args.only:
        record(
            "Classical gap: the changes on colour ICX285 captures (issue 29)",
            colour_rows(COLOUR_PHOTOS),
            notes="ICX285 at 300 photons/px/ms as in bench_deconvolve.py; the sensor's noise "
            f"model; SURE_SHRINK {sparse.SURE_SHRINK}",
        )


if __name__ == "__main__":
    main()
