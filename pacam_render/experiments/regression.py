"""Regression images: small stored renders and a noise-aware comparison with fresh ones.

Each case is rendered with two seeds and stored as one EXR (layers ``seed0``, ``seed1``) in
``tests/regression/``. A fresh render with a third seed is compared with their mean, pixel by
pixel, in units of the Monte Carlo standard error that the two stored seeds estimate:

    z = (fresh - mean) / sqrt(1.5 v),   v = mean box5((seed0 - seed1)^2 / 2) / box5(mean)

(the fresh image carries one render's variance v, the mean half of it; Monte Carlo variance
grows with the signal, so the 5x5 box smooths the one-degree-of-freedom estimate relative to the
signal). A case rendered in many passes (:data:`PASS_VARIANCE`) brings its own per-pixel
variance instead, from the spread of its passes: the moving point's noise is mostly where its
random step times move it across a pixel edge, which does not grow with the signal, so there
z = (fresh - mean) / sqrt(s_f^2 + (s_0^2 + s_1^2) / 4) with each render's recorded ``mc_sigma``
(15 degrees of freedom), pooled as sum(d^2) / sum(var) (limit :data:`POOLED_Z2_LIMIT`). Pixels
darker than 1e-4 of the brightest are left out (a PSF scene is mostly black).
The fresh image matches when mean(min(z^2, 25)) < 1.5, fewer than 1 % of pixels have |z| > 5,
and its total brightness agrees within 4 standard errors (estimated from 15x15-pixel tile sums
of seed0 - seed1, which keeps correlated noise). So Monte Carlo noise passes, while a one-pixel
shift or a 2 % change of brightness fails.

Re-create the references with ``make bless`` after an intended change to what is rendered.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

from ..errors import ParameterError
from ..exposure.camera import capture_design
from ..exposure.direct import render_capture
from ..exposure.spec import CAMERA_OPTICS, CaptureSpec
from ..io.exr import read_exr, write_exr
from ..scenes import psf_scene

FOLDER = Path(__file__).resolve().parents[2] / "tests" / "regression"
SIZE = {"width": 120, "height": 90, "spp": 64, **CAMERA_OPTICS, "diffraction": "off"}
"""Every case through a camera's optics (issue 36: re-blessed with them). At 120x90 (the
sensor binned 10.7x) the Airy pattern is a tenth of a pixel and ``auto`` leaves diffraction
out, so it is named ``off``: the same bits without ``auto``'s preview render (a test holds
both)."""
CASES = {
    f"train_{m}": CaptureSpec(scene="train", mode=m, **SIZE)
    for m in ("normal", "coded", "short", "levin", "flutter")
}
CASES["train_reference"] = CaptureSpec.geometric(scene="train", mode="reference", width=120,
                                                 height=90, spp=64)  # fmt: skip  # the pinhole
CASES["psf_coded"] = CaptureSpec(  # 16 passes of 72 steps x 4 spp: what was blessed
    scene="psf", mode="coded", width=64, height=24, spp=4608, passes=16, **CAMERA_OPTICS
)
PASS_VARIANCE = 8
"""Cases of at least this many passes are compared with their own per-pixel variance."""
POOLED_Z2_LIMIT = 2.5
"""The pooled z^2 limit of those cases: a moving point's noise is correlated along its streak,
so the statistic has few degrees of freedom (measured 0.79 to 1.61 over seeds 2-6); a 1-px
shift still fails by its outliers (14 % and 77 %) and a 2 % brightness change by 57 SE."""
FRESH_SEED = 2


def render_case(name: str, seed: int) -> np.ndarray:
    """A case's image for one seed, float64 (H, W, 3)."""
    return render_case_sigma(name, seed)[0]


def render_case_sigma(name: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A case's image and per-pixel Monte Carlo sigma for one seed, float64 (H, W, 3)."""
    if name not in CASES:
        raise ParameterError(f"unknown regression case {name!r}; valid: {', '.join(CASES)}")
    spec = replace(CASES[name], seed=seed)
    desc = None
    if spec.scene == "psf":
        desc = psf_scene(500.0, 0.8, camera=capture_design(spec), radius_mm=8.0)
    cap = render_capture(spec, progress=False, description=desc, truth=False)
    return cap.image, cap.mc_sigma


@dataclass
class Verdict:
    mean_z2: float
    frac_outliers: float
    brightness_ratio: float
    brightness_z: float
    z2_limit: float = 1.5

    @property
    def ok(self) -> bool:
        return (
            self.mean_z2 < self.z2_limit
            and self.frac_outliers < 0.01
            and abs(self.brightness_z) < 4
        )

    def __str__(self) -> str:
        return (
            f"mean z^2 = {self.mean_z2:.3f} (< {self.z2_limit:g}), |z| > 5: "
            f"{self.frac_outliers:.2%} "
            f"(< 1 %), brightness x{self.brightness_ratio:.4f} ({self.brightness_z:+.1f} SE)"
        )


def _tile_variance(diff: np.ndarray, tile: int = 15) -> float:
    """Variance of diff.sum() from sums over tiles: keeps noise correlated between pixels."""
    h, w = diff.shape[:2]
    sums = [
        diff[i : i + tile, j : j + tile].sum() for i in range(0, h, tile) for j in range(0, w, tile)
    ]
    return float(np.sum(np.square(sums)))


def compare(
    fresh: np.ndarray, seed0: np.ndarray, seed1: np.ndarray, sigmas: tuple | None = None
) -> Verdict:
    """Noise-aware comparison of a fresh render with two stored seeds; ``sigmas`` (fresh,
    seed0, seed1), each render's per-pixel Monte Carlo sigma, replace the estimate from the
    two seeds (cases of many passes)."""
    if not fresh.shape == seed0.shape == seed1.shape:
        raise ParameterError(f"shapes differ: {fresh.shape}, {seed0.shape}, {seed1.shape}")
    mean = 0.5 * (seed0 + seed1)
    if sigmas is None:
        # Monte Carlo variance grows with the signal: smooth variance / signal, then scale back
        box = {"size": (5, 5, 1), "mode": "nearest"}
        level = np.maximum(mean, 0.0)
        ratio = uniform_filter(0.5 * (seed0 - seed1) ** 2, **box) / (
            uniform_filter(level, **box) + 1e-30
        )
        v = 1.5 * ratio * level
    else:
        s_f, s_0, s_1 = sigmas
        v = s_f**2 + 0.25 * (s_0**2 + s_1**2)
    floor = 1e-12 + 1e-6 * float(np.mean(v))  # black pixels of a PSF scene have v = 0
    var = v + floor
    lit = (mean + np.abs(fresh)) > 1e-4 * float(mean.max())  # a PSF scene is mostly black
    z2 = ((fresh - mean) ** 2 / var)[lit]
    total_se = float(np.sqrt(1.5 * _tile_variance(seed0 - seed1) / 2.0))
    diff = float(fresh.sum() - mean.sum())
    if sigmas is not None:  # pooled: a ratio of sums is steadier than a mean of ratios
        d2 = ((fresh - mean) ** 2)[lit]
        z2_mean = float(np.minimum(d2, 25.0 * var[lit]).sum() / var[lit].sum())
    else:
        z2_mean = float(np.minimum(z2, 25.0).mean())
    return Verdict(
        mean_z2=z2_mean,
        frac_outliers=float((z2 > 25.0).mean()),
        brightness_ratio=float(fresh.sum() / mean.sum()),
        brightness_z=diff / total_se,
        z2_limit=1.5 if sigmas is None else POOLED_Z2_LIMIT,
    )


def load_reference(name: str, folder: Path = FOLDER) -> tuple[np.ndarray, np.ndarray]:

    layers = read_exr(folder / f"{name}.exr")
    return layers["seed0"].astype(np.float64), layers["seed1"].astype(np.float64)


def check(name: str, fresh: np.ndarray, fresh_sigma: np.ndarray, folder: Path = FOLDER):
    """:func:`compare` of a fresh render of case ``name`` with its references, with their
    recorded sigmas for a case of :data:`PASS_VARIANCE` passes or more."""

    layers = read_exr(folder / f"{name}.exr")
    seeds = [layers[f"seed{s}"].astype(np.float64) for s in (0, 1)]
    sigmas = None
    if CASES[name].passes >= PASS_VARIANCE:
        sigmas = (fresh_sigma, *(layers[f"sigma{s}"].astype(np.float64) for s in (0, 1)))
    return compare(fresh, *seeds, sigmas)


def bless(folder: Path = FOLDER, names=None) -> list[Path]:
    """Re-render and store the references (seeds 0 and 1). Overwrites: that is its purpose."""

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name in names or CASES:
        layers = {}
        for s in (0, 1):
            layers[f"seed{s}"], sigma = render_case_sigma(name, s)
            if CASES[name].passes >= PASS_VARIANCE:
                layers[f"sigma{s}"] = sigma
        out.append(write_exr(folder / f"{name}.exr", layers, force=True))
        print(f"blessed {out[-1]}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Regression images: bless or check")
    ap.add_argument("--bless", action="store_true", help="re-create the stored references")
    ap.add_argument("--folder", default=str(FOLDER))
    args = ap.parse_args(argv)
    folder = Path(args.folder)
    if args.bless:
        bless(folder)
        return 0
    bad = 0
    for name in CASES:
        v = check(name, *render_case_sigma(name, FRESH_SEED), folder)
        print(f"{name}: {'ok' if v.ok else 'CHANGED'}  {v}")
        bad += not v.ok
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
