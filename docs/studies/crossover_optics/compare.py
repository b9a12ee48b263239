"""The crossover with a camera's optics against the geometric run: writes comparison.md.

Pairs each row of ``previous/results.csv`` (this study's run before issues 45 and 46: the
rays' Airy draw, the oracle's model error; diffraction auto, relative illumination cos4,
flat-fielded) with the ``crossover`` study's row of the same mode, speed, light level, method
and seed (the prototype's design for ``coded``), rendered with geometric optics in radiance.
Crossing light levels are found per seed (log-linear between light levels, the report's
rule) and given as their geometric mean with a 95 % t-interval over the three seeds.

    python docs/studies/crossover_optics/compare.py
"""

from __future__ import annotations

import csv
import math
import statistics as st
from pathlib import Path

HERE = Path(__file__).resolve().parent
OLD = HERE.parent / "crossover" / "results.csv"
OPTICS = HERE / "previous" / "results.csv"  # the run this comparison was written from
T95_2DOF = 4.303  # Student's t, 97.5 % quantile, 2 degrees of freedom (3 seeds)
SEEDS = ("0", "1", "2")


def _rows(path: Path, prototype_only: bool) -> dict:
    out = {}
    for r in csv.DictReader(open(path)):
        if r["status"] != "ok" or r["method"] != "hl" or float(r["speed_px_per_ms"]) != 0.7:
            continue
        if prototype_only and r["mode"] == "coded" and r["design"] != "prototype":
            continue
        out[(r["mode"], r["seed"], float(r["light_level_photons_per_px_per_ms"]))] = r
    return out


def _crossing(rows: dict, other: str, seed: str, lights) -> float:
    d = [
        (x, float(rows[("coded", seed, x)]["psnr_moving_db"])
         - float(rows[(other, seed, x)]["psnr_moving_db"]))
        for x in lights
    ]  # fmt: skip
    for (x0, d0), (x1, d1) in zip(d, d[1:]):
        if d0 * d1 < 0:
            return math.exp(math.log(x0) + d0 / (d0 - d1) * (math.log(x1) - math.log(x0)))
    return math.nan


def _interval(xs) -> str:
    logs = [math.log10(x) for x in xs]
    m, h = st.mean(logs), T95_2DOF * st.stdev(logs) / math.sqrt(len(logs))
    return f"{10**m:.1f} ({10 ** (m - h):.1f}-{10 ** (m + h):.1f})"


def main() -> None:
    new, old = _rows(OPTICS, False), _rows(OLD, True)
    lights = sorted({k[2] for k in new})
    lines = [
        "# The crossover with a camera's optics against the geometric run",
        "",
        "Written by `compare.py` from `previous/results.csv` (this study before issues 45 and "
        "46: the Airy draw, the oracle) and `../crossover/results.csv`"
        " (0.7 px/ms, hl, the prototype's coded design, seeds 0-2, light levels "
        f"{', '.join(f'{x:g}' for x in lights)} photons/px/ms).",
        "",
        "## Crossing light levels (photons/px/ms, geometric mean over seeds, 95 % interval)",
        "",
        "| coded against | geometric, radiance | diffraction auto + cos4 flat-fielded |",
        "|---|---|---|",
    ]
    for other in ("short", "normal"):
        a = [_crossing(old, other, s, lights) for s in SEEDS]
        b = [_crossing(new, other, s, lights) for s in SEEDS]
        lines.append(f"| {other} | {_interval(a)} | {_interval(b)} |")
    lines += [
        "",
        "## Moving objects' PSNR by light level (dB, mean over seeds)",
        "",
        "| mode | light | geometric | with optics | change (sd over seeds) | diffraction "
        "| noise sigma ratio | model sigma, geometric / optics |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for mode in ("coded", "normal", "short"):
        for x in lights:
            pairs = [(new[(mode, s, x)], old[(mode, s, x)]) for s in SEEDS]
            diff = [float(n["psnr_moving_db"]) - float(o["psnr_moving_db"]) for n, o in pairs]
            ratio = st.mean(float(n["noise_sigma"]) / float(o["noise_sigma"]) for n, o in pairs)
            states = ", ".join(sorted({n["diffraction"] for n, _ in pairs}))
            mo = st.mean(float(o["model_sigma"]) for _, o in pairs)
            mn = st.mean(float(n["model_sigma"]) for n, _ in pairs)
            lines.append(
                f"| {mode} | {x:g} | {st.mean(float(o['psnr_moving_db']) for _, o in pairs):.2f}"
                f" | {st.mean(float(n['psnr_moving_db']) for n, _ in pairs):.2f} | "
                f"{st.mean(diff):+.2f} ({st.stdev(diff):.2f}) | {states} | {ratio:.3f} | "
                f"{mo:.4f} / {mn:.4f} |"
            )
    (HERE / "comparison.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
