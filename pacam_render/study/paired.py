"""Paired differences between designs, for a study on light-field stores.

In a ``[render] lightfield = true`` study every design and mode of a scene, speed and seed is
synthesised from one store, so their scores share the store's random numbers: a difference
between two designs, seed by seed, is far less noisy than the difference of their means over
independent renders. The section gives, for each capture against the study's first, the mean
difference of ``psnr_moving_db`` over the seeds with its 95 % Student-t interval.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

LIGHT = "light_level_photons_per_px_per_ms"
SETTING = ("scene", "speed_px_per_ms", "depth_mm", LIGHT, "sensor", "method")
"""What a paired difference holds fixed: everything but the capture (mode and design) and
the seed."""


def paired_differences(rows: list[dict], y: str = "psnr_moving_db") -> list[dict]:
    """Per setting and capture, the seeds' differences of ``y`` against the first capture.

    Returns
    -------
    list of dict
        ``capture``, ``reference``, the setting's fields, ``n`` (seeds), ``mean`` (dB) and
        ``half`` (95 % half-width, dB; 0 for one seed).
    """
    from scipy.stats import t as student

    captures = list(dict.fromkeys((r["mode"], r["design"]) for r in rows))
    if len(captures) < 2:
        return []
    ref = captures[0]
    by = defaultdict(dict)
    for r in rows:
        by[(tuple(r[k] for k in SETTING), r["seed"])][(r["mode"], r["design"])] = float(r[y])
    diffs = defaultdict(list)
    for (setting, _), values in by.items():
        for cap in captures[1:]:
            if cap in values and ref in values:
                diffs[(setting, cap)].append(values[cap] - values[ref])
    out = []
    for (setting, cap), d in diffs.items():
        n = len(d)
        half = student.ppf(0.975, n - 1) * np.std(d, ddof=1) / np.sqrt(n) if n > 1 else 0.0
        out.append({"capture": " ".join(cap), "reference": " ".join(ref),
                    **dict(zip(SETTING, setting)), "n": n, "mean": float(np.mean(d)),
                    "half": float(half)})  # fmt: skip
    return out


def paired_section(rows: list[dict]) -> list[str]:
    """The report's section (module docstring); empty with fewer than two captures."""
    diffs = paired_differences(rows)
    if not diffs:
        return []
    lines = [
        "## Paired differences between designs (one light-field store per scene, speed and seed)",
        "",
        f"PSNR on the moving objects against `{diffs[0]['reference']}`, seed by seed (both "
        "captures synthesised from the same store), mean and 95 % interval over the seeds.",
        "",
        "| capture | speed (px/ms) | light | method | mean difference (dB) | 95 % interval "
        "| seeds |",
        "|---|---|---|---|---|---|---|",
    ]
    for d in diffs:
        lines.append(
            f"| {d['capture']} | {d['speed_px_per_ms']:.3g} | {d[LIGHT]:.4g} | {d['method']} | "
            f"{d['mean']:+.2f} | {d['mean'] - d['half']:+.2f} to {d['mean'] + d['half']:+.2f} | "
            f"{d['n']} |"
        )
    return [*lines, ""]
