"""The error of the convolution model against a rendered scene, in units of the Monte Carlo
noise: per region (:mod:`.scene_regions`) and against the distance to a moving edge, for
``pacam validate-scene`` (:mod:`.validate_scene`) and its files (:mod:`.scene_report`).

Noise floor: with c the capture and m the model of one seed, the error of the mean of the two
seeds is e = (c1 + c2)/2 - (m1 + m2)/2, and d = (c1 - c2) - (m1 - m2) holds only noise. If
the model were exact, E[e^2] = E[d^2] / 4. So in each region ``ratio = rms(e) / rms(d / 2)``
is the error in units of the Monte Carlo noise (1 at the floor), and
``model_rms = sqrt(mean(e^2) - mean(d^2) / 4)`` is the model's own error with the noise taken
out, white = 1. ``psnr_ceiling_db = -10 log10(model_rms^2)`` is the PSNR of the
model against a noiseless capture there: a deconvolution that inverts the model explains the
capture no better than that. A region is ``at_floor`` when ratio^2 - 1 is within three of its
standard errors (2 / sqrt(pixels)) of 0.
"""

from __future__ import annotations

import math

import numpy as np

from .scene_regions import REGIONS


def residuals(captures, predicted) -> tuple[np.ndarray, np.ndarray]:
    """e, the error of the two seeds' mean, and d, their difference that holds only noise
    (see the module docstring)."""
    (c1, c2), (m1, m2) = captures, predicted
    return 0.5 * (c1 + c2) - 0.5 * (m1 + m2), (c1 - c2) - (m1 - m2)


def region_rows(captures, predicted, reg: np.ndarray, model: str) -> list[dict]:
    """The error of one model in every region, in noise units (see the module docstring)."""
    e, d = residuals(captures, predicted)
    rows = []
    names = [n for n in REGIONS if n != "frame"] + ["all"]
    for name in names:
        sel = reg != 0 if name == "all" else reg == REGIONS.index(name)
        n = int(sel.sum())
        if n == 0:
            continue
        rows.append({"model": model, "region": name, "pixels": n, **_stats(e[sel], d[sel], n)})
    return rows


PROFILE_STEP_PX = 2.0
"""Width of the distance bins of the edge profile, px."""
PROFILE_RATIO = 1.1
"""The edge profile's width ends where the error stays below this many noise sigmas (or at
the floor)."""


def edge_profile(captures, predicted, reg, dist, model: str, reach_px: float) -> list[dict]:
    """The error against signed distance to a moving edge (negative: inside the object)."""
    e, d = residuals(captures, predicted)
    n = math.ceil(reach_px / PROFILE_STEP_PX) + 1
    rows = []
    for k in range(-n, n):
        lo = k * PROFILE_STEP_PX
        sel = (reg != 0) & (dist >= lo) & (dist < lo + PROFILE_STEP_PX)
        if sel.sum() >= 50:
            row = {
                "model": model,
                "distance_px": lo + 0.5 * PROFILE_STEP_PX,
                "pixels": int(sel.sum()),
            }
            rows.append({**row, **_stats(e[sel], d[sel], int(sel.sum()))})
    return rows


def profile_width(profile: list[dict]) -> tuple[float, float]:
    """How far inside and outside a moving edge the error is above the noise, px: the farthest
    bin on each side whose ratio exceeds :data:`PROFILE_RATIO` and is not at the floor
    (0 if none)."""
    out = []
    for side in (-1, 1):
        bad = [
            side * r["distance_px"]
            for r in profile
            if side * r["distance_px"] > 0 and r["ratio"] > PROFILE_RATIO and not r["at_floor"]
        ]
        out.append(max(bad, default=0.0) + (0.5 * PROFILE_STEP_PX if bad else 0.0))
    return out[0], out[1]


def _stats(e: np.ndarray, d: np.ndarray, n: int) -> dict:
    e2, n2 = float(np.mean(e**2)), float(np.mean(d**2)) / 4.0
    if n2 > 0:
        ratio = math.sqrt(e2 / n2)
    else:  # no noise (a black region): exact agreement is the floor, anything else is not
        ratio = 1.0 if e2 == 0 else math.inf
    excess = e2 - n2
    return {
        "noise_rms": math.sqrt(n2),
        "error_rms": math.sqrt(e2),
        "ratio": ratio,
        "model_rms": math.sqrt(max(excess, 0.0)),
        "psnr_ceiling_db": -10.0 * math.log10(excess) if excess > 0 else math.inf,
        "bias": float(np.mean(e)),
        "at_floor": bool(ratio**2 - 1.0 <= 3.0 * 2.0 / math.sqrt(n)),
    }
