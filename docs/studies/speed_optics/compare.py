"""The speed study with a camera's optics against the geometric run: writes comparison.md.

Pairs each row of this folder's results.csv (diffraction auto, relative illumination cos4,
flat-fielded) with the ``speed`` study's row of the same mode, design and speed (seed 0, the
shipped spec's only seed), rendered with geometric optics in radiance. One seed: the changes
are paired differences of one render each, so no interval is given; the crossover re-run's
three seeds put the sd of such a change at 0.01-0.17 dB.

    python docs/studies/speed_optics/compare.py
"""

from __future__ import annotations

import csv
from pathlib import Path

HERE = Path(__file__).resolve().parent
OLD = HERE.parent / "speed" / "results.csv"
SCORES = (("psnr_moving_db", "moving objects"), ("psnr_moving_interior_db", "their interiors"))


def _rows(path: Path) -> dict:
    return {
        (r["mode"], r["design"], float(r["speed_px_per_ms"])): r
        for r in csv.DictReader(open(path))
        if r["status"] == "ok"
    }


def _spread(rows: dict, mode: str, design: str, key: str) -> tuple[float, float]:
    vals = [float(r[key]) for (m, d, _), r in rows.items() if (m, d) == (mode, design)]
    return min(vals), max(vals)


def main() -> None:
    new, old = _rows(HERE / "results.csv"), _rows(OLD)
    keys = sorted(new, key=lambda k: (k[0] != "coded", k[1], k[2]))
    designs = sorted({k[:2] for k in keys}, key=lambda k: (k[0] != "coded", k[1]))
    lines = [
        "# The speed study with a camera's optics against the geometric run",
        "",
        "Written by `compare.py` from this folder's `results.csv` and `../speed/results.csv`"
        " (soccer, 300 photons/px/ms, hl, seed 0; rows paired by mode, design and speed).",
        "",
        "## Flatness over speed (dB: lowest to highest PSNR over the speeds, and the spread)",
        "",
        "| mode, design | score | geometric | with optics |",
        "|---|---|---|---|",
    ]
    for mode, design in designs:
        for key, what in SCORES:
            cells = []
            for rows in (old, new):
                lo, hi = _spread(rows, mode, design, key)
                cells.append(f"{lo:.2f} to {hi:.2f} ({hi - lo:.2f})")
            lines.append(f"| {mode} {design} | {what} | {cells[0]} | {cells[1]} |")
    lines += [
        "",
        "## Moving objects' PSNR by speed (dB)",
        "",
        "| mode, design | speed (px/ms) | geometric | with optics | change | diffraction "
        "| noise sigma ratio | model sigma, geometric / optics |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k in keys:
        n, o = new[k], old[k]
        a, b = float(o["psnr_moving_db"]), float(n["psnr_moving_db"])
        ratio = float(n["noise_sigma"]) / float(o["noise_sigma"])
        lines.append(
            f"| {k[0]} {k[1]} | {k[2]:g} | {a:.2f} | {b:.2f} | {b - a:+.2f} | "
            f"{n['diffraction']} | {ratio:.3f} | {float(o['model_sigma']):.4f} / "
            f"{float(n['model_sigma']):.4f} |"
        )
    (HERE / "comparison.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
