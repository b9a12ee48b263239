"""Deconvolution benchmark (issues 6 and 16): speed against scikit-image's Wiener, and PSNR, SSIM
and run time of every method on 13 photographs through the prototype's coded PSF.

Captures: the scikit-image photographs that ship offline, 256 x 256, blurred by linear
convolution of the reflect-extended scene with the prototype's discrete coded PSF (s = 0);
(a) grey with Gaussian noise sigma = 0.01, (b) colour through the ICX285 sensor model (Bayer,
Poisson-Gaussian, 14 bits) at 300 photons/px/ms, the coded opening and 45 ms, demosaicked.
Every method gets the noise it should assume: sigma, or for hl/tv on (b) the sensor's
Poisson-Gaussian model. Also: hl/tv's options on (b) (colour joint or per channel, white or
Poisson-Gaussian noise); PSNR against iterations and seconds; the speed-robust kernel on
objects at 0, 0.5 and 1.0 times the invariant range.

    python benchmarks/bench_deconvolve.py [--no-bm3d] [--no-pnp] [--only-methods]
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import numpy as np
from common import median_spread, record, timeit
from scipy.signal import fftconvolve
from skimage import color, data, transform
from skimage.metrics import structural_similarity
from skimage.restoration import wiener as sk_wiener

from pacam_render import prototype
from pacam_render.psf.analytic import design_psf
from pacam_render.psf.robust import aligned_speed_psf, speed_robust_psf
from pacam_render.restore import deconvolve as D
from pacam_render.restore.metrics import psnr
from pacam_render.restore.noise import NoiseModel
from pacam_render.restore.sparse import sparse_deconvolve
from pacam_render.sensor.model import SensorModel, simulate_capture
from pacam_render.sensor.radiometry import aperture_area_mm2

SIGMA = 0.01
PHOTOS = (
    "astronaut",
    "brick",
    "camera",
    "chelsea",
    "clock",
    "coffee",
    "coins",
    "grass",
    "gravel",
    "hubble_deep_field",
    "moon",
    "retina",
    "rocket",
)
LIGHT = 300.0  # photons/px/ms, the demo's
CAM = prototype()
K = design_psf(CAM, "coded", 0.0)
SENSOR = SensorModel.from_preset("grasshopper-icx285")


def photo(name: str, rgb: bool) -> np.ndarray:
    x = getattr(data, name)() / 255.0
    if x.ndim == 2 and rgb:
        x = np.repeat(x[..., None], 3, axis=2)
    elif x.ndim == 3 and not rgb:
        x = color.rgb2gray(x)
    return np.clip(transform.resize(x, (256, 256), anti_aliasing=True), 0.0, 1.0)


def blur(x: np.ndarray, k: np.ndarray = K) -> np.ndarray:
    if x.ndim == 3:
        return np.stack([blur(x[..., c], k) for c in range(x.shape[2])], axis=-1)
    pad = k.shape[0]
    return fftconvolve(np.pad(x, pad, mode="reflect"), k, mode="same")[pad:-pad, pad:-pad]


def grey_capture(x: np.ndarray, seed: int = 0):
    y = blur(x) + np.random.default_rng(seed).normal(0, SIGMA, x.shape)
    return y, {"noise_sigma": SIGMA}, {"noise_sigma": SIGMA}


def sensor_capture(x: np.ndarray, seed: int = 0):
    area = {"open_area_mm2": aperture_area_mm2(CAM.R_mm)}
    area["reference_area_mm2"] = aperture_area_mm2(CAM.R_max_mm)
    res = simulate_capture(
        np.clip(blur(x), 0, None), SENSOR, exposure_ms=45.0, seed=seed, light_level=LIGHT, **area
    )
    noise = NoiseModel.from_sensor(SENSOR, SENSOR.qe * res.photons_per_unit, 45.0)
    y = res.linear.astype(float)
    white = {"noise_sigma": float(np.sqrt(noise.variance(y.mean())))}
    return y, white, {"noise": noise}


def methods(bm3d: bool, pnp: bool) -> dict:
    """Every method of ``deconvolve``, and hl/tv's per-image weight: label -> fn(y, white,
    own), where white holds the white sigma and own the noise a method should assume."""
    runs = {
        "none (blurred input)": lambda y, w, s: y,
        "wiener": lambda y, w, s: D.wiener(y, K, **w),
        "uwiener": lambda y, w, s: D.unsupervised_wiener(y, K, seed=0),
        "hl": lambda y, w, s: sparse_deconvolve(y, K, "hl", **s),
        "tv": lambda y, w, s: sparse_deconvolve(y, K, "tv", **s),
        "hl, lambda_scale sure": lambda y, w, s: sparse_deconvolve(
            y, K, "hl", lambda_scale="sure", **s
        ),
        "tv, lambda_scale sure": lambda y, w, s: sparse_deconvolve(
            y, K, "tv", lambda_scale="sure", **s
        ),
        "richardson-lucy 30 it": lambda y, w, s: D.richardson_lucy(np.clip(y, 0, None), K, 30),
    }
    if bm3d:
        runs["bm3d deblurring"] = lambda y, w, s: D.bm3d_deblur(y, K, w["noise_sigma"])
    if pnp:
        runs["pnp"] = lambda y, w, s: D.deconvolve(y, K, "pnp", **w)
    return runs


def quality_rows(capture, rgb: bool, bm3d: bool, pnp: bool, per_photo: list) -> list[dict]:
    """Mean, min and max PSNR, SSIM and seconds per method; ``per_photo`` gets a row of PSNR
    per photograph."""
    scores: dict[str, list] = {}
    if pnp:  # jax compiles the network for this shape before any timing
        y, white, _ = capture(photo(PHOTOS[0], rgb))
        D.deconvolve(y, K, "pnp", **white)
    for name in PHOTOS:
        x = photo(name, rgb)
        y, white, own = capture(x)
        per_photo.append({"photo": name})
        for label, fn in methods(bm3d, pnp).items():
            t0 = time.perf_counter()
            est = fn(y, white, own)
            dt = time.perf_counter() - t0
            ssim = structural_similarity(
                np.clip(est, 0, 1), x, data_range=1.0, channel_axis=2 if rgb else None
            )
            scores.setdefault(label, []).append((psnr(est, x), ssim, dt))
            per_photo[-1][label] = psnr(est, x)
    rows = []
    for label, v in scores.items():
        a = np.array(v)
        rows.append(
            {
                "method": label,
                "mean PSNR dB": a[:, 0].mean(),
                "min dB": a[:, 0].min(),
                "max dB": a[:, 0].max(),
                "mean SSIM": a[:, 1].mean(),
                "median s": float(np.median(a[:, 2])),
            }
        )
    return rows


def option_rows() -> list[dict]:
    rows = []
    xs = [photo(n, True) for n in PHOTOS]
    caps = [sensor_capture(x) for x in xs]
    for method in ("hl", "tv"):
        for colour in ("joint", "channel"):
            for noise in ("white", "sensor"):
                got = []
                for x, (y, white, own) in zip(xs, caps):
                    kw = white if noise == "white" else own
                    got.append(psnr(sparse_deconvolve(y, K, method, colour=colour, **kw), x))
                rows.append(
                    {"method": method, "colour": colour, "noise": noise, "mean dB": np.mean(got)}
                )
    return rows


def iteration_rows() -> list[dict]:
    rows = []
    xs = [photo(n, False) for n in PHOTOS[:4]]
    ys = [grey_capture(x)[0] for x in xs]
    for method in ("hl", "tv"):
        for n in (1, 2, 3, 6, 9, 12, 24):
            t0 = time.perf_counter()
            got = [
                psnr(sparse_deconvolve(y, K, method, SIGMA, iterations=n), x)
                for x, y in zip(xs, ys)
            ]
            rows.append(
                {
                    "method": method,
                    "iterations": n,
                    "mean dB": np.mean(got),
                    "s per image": (time.perf_counter() - t0) / len(xs),
                }
            )
    for n in (5, 10, 30, 60):
        t0 = time.perf_counter()
        got = [psnr(D.richardson_lucy(np.clip(y, 0, None), K, n), x) for x, y in zip(xs, ys)]
        rows.append(
            {
                "method": "rl",
                "iterations": n,
                "mean dB": np.mean(got),
                "s per image": (time.perf_counter() - t0) / len(xs),
            }
        )
    return rows


def robust_rows() -> list[dict]:
    kr = speed_robust_psf(CAM)
    k0 = aligned_speed_psf(CAM, "coded", 0.0, size=kr.shape)
    xs = [photo(n, False) for n in PHOTOS[:4]]
    rows = []
    for frac in (0.0, 0.5, 1.0):
        ks = aligned_speed_psf(CAM, "coded", frac * CAM.velocity_range_px_per_ms, size=kr.shape)
        ys = [blur(x, ks) + np.random.default_rng(0).normal(0, SIGMA, x.shape) for x in xs]
        row = {"s / range": frac}
        for label, k in (("s = 0 kernel", k0), ("robust kernel", kr)):
            for m in ("wiener", "hl"):
                est = [D.deconvolve(y, k, m, noise_sigma=SIGMA) for y in ys]
                row[f"{m}, {label} dB"] = np.mean([psnr(e, x) for e, x in zip(est, xs)])
        rows.append(row)
    return rows


def speed_rows(repeat: int = 5) -> list[dict]:
    rows = []
    for shape in [(512, 512), (960, 1280)]:
        x = transform.resize(color.rgb2gray(data.astronaut()), shape, anti_aliasing=True)
        y = blur(x) + np.random.default_rng(0).normal(0, SIGMA, shape)
        ours = median_spread(timeit(lambda y=y: D.wiener(y, K, nsr=1e-2), repeat))
        theirs = median_spread(timeit(lambda y=y: sk_wiener(y, K, 1e-2, clip=False), repeat))
        rows.append(
            {
                "image": f"{shape[1]}x{shape[0]}",
                "ours_ms": 1e3 * ours[0],
                "skimage_ms": 1e3 * theirs[0],
                "ratio": ours[0] / theirs[0],
            }
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-bm3d", action="store_true", help="leave out BM3D (minutes)")
    ap.add_argument("--no-pnp", action="store_true", help="leave out pnp (minutes)")
    ap.add_argument("--skip-grey", action="store_true", help="leave out the speed and grey runs")
    ap.add_argument("--only-methods", action="store_true", help="only the two method tables")
    args = ap.parse_args()
    bm3d_ok = not args.no_bm3d and importlib.util.find_spec("bm3d") is not None
    pnp_ok = not args.no_pnp and importlib.util.find_spec("scico") is not None
    if not args.skip_grey:
        grey_sections(bm3d_ok, pnp_ok, args.only_methods)
    colour_sections(bm3d_ok, pnp_ok, args.only_methods)


def method_sections(title: str, capture, rgb: bool, bm3d_ok: bool, pnp_ok: bool, notes: str):
    """The mean table of every method and the per-photograph PSNR table, recorded."""
    per_photo: list[dict] = []
    record(title, quality_rows(capture, rgb, bm3d_ok, pnp_ok, per_photo), notes=notes)
    record(f"{title}: PSNR dB per photograph", per_photo, notes=notes)


def grey_sections(bm3d_ok: bool, pnp_ok: bool, only_methods: bool) -> None:
    if not only_methods:
        record(
            "Deconvolution speed: pacam Wiener vs skimage.restoration.wiener",
            speed_rows(),
            notes="grey, prototype coded PSF 25x25; ours pads and tapers, skimage wraps",
        )
    method_sections(
        f"(a) Deconvolution of 13 photographs, grey, sigma = {SIGMA} (issues 16, 29)",
        grey_capture,
        False,
        bm3d_ok,
        pnp_ok,
        "256x256 each, prototype coded PSF (s = 0), every method told sigma; seconds per "
        "image on 2 shared cores, side by side",
    )


def colour_sections(bm3d_ok: bool, pnp_ok: bool, only_methods: bool) -> None:
    method_sections(
        f"(a) Deconvolution of 13 photographs, colour, ICX285 at {LIGHT:g} photons/px/ms",
        sensor_capture,
        True,
        bm3d_ok,
        pnp_ok,
        "Bayer RGGB, bilinear demosaic, coded opening F9.85, 45 ms; hl/tv get the "
        "sensor's Poisson-Gaussian model, wiener/bm3d/pnp the sigma at the mean level; "
        "pnp per channel",
    )
    if only_methods:
        return
    record(
        "hl/tv options on the ICX285 captures (issue 16)",
        option_rows(),
        notes="13 colour photographs as above; colour: one prior per gradient colour vector "
        "(joint) or per channel; noise: white at the mean level or the sensor's model",
    )
    record(
        "PSNR against iterations and run time (issue 16)",
        iteration_rows(),
        notes=f"4 grey photographs, sigma {SIGMA}; hl/tv: beta geometric from BETA_START to "
        "the method's sparse.SCHEDULE stop in n steps",
    )
    record(
        "Speed-robust kernel against the s = 0 kernel (issue 16)",
        robust_rows(),
        notes="4 grey photographs blurred with the vertex-aligned coded PSF at s; the robust "
        f"kernel averages it over |s| <= {CAM.velocity_range_px_per_ms:.3g} px/ms (33 speeds)",
    )


if __name__ == "__main__":
    main()
