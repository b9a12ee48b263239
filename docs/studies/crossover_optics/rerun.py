"""This study re-run after issues 45 and 46 against its run before: writes rerun.md.

Two changes between the runs, separated on the same renders by the new run's
``psnr_moving_oracle_db`` column (the capture restored as before, told its own model error):

- issue 45: the rays draw the exact defocused PSF (the coupling of
  ``render/kernels/defocus_draw.py``) instead of the geometric disc convolved with the Airy pattern:
  ``oracle (now)`` against ``before``;
- issue 46: by default the deconvolver is told what a real camera knows, the sensor's noise
  (per pixel) and the render's, not the capture's model error measured against its own
  ``sharp`` layer (the oracle): ``default (now)`` against ``oracle (now)``.

Crossings are found per seed, as ``compare.py`` finds them.

    python docs/studies/crossover_optics/rerun.py
"""

from __future__ import annotations

import statistics as st
from pathlib import Path

from compare import SEEDS, _crossing, _interval, _rows

HERE = Path(__file__).resolve().parent
ORACLE = "psnr_moving_oracle_db"


def _as_oracle(rows: dict) -> dict:
    """The rows with the oracle's score as the moving objects' (modes told no model error
    have the same score either way)."""
    return {k: {**r, "psnr_moving_db": r[ORACLE] or r["psnr_moving_db"]} for k, r in rows.items()}


def _mean(rows: dict, mode: str, light: float) -> float:
    return st.mean(float(rows[(mode, s, light)]["psnr_moving_db"]) for s in SEEDS)


def main() -> None:
    before = _rows(HERE / "previous" / "results.csv", False)
    now = _rows(HERE / "results.csv", False)
    oracle = _as_oracle(now)
    lights = sorted({k[2] for k in now})
    runs = (("before", before), ("oracle (now)", oracle), ("default (now)", now))
    lines = [
        "# The re-run after issues 45 and 46",
        "",
        "Written by `rerun.py` from `previous/results.csv` (the Airy draw in the rays, the "
        "deconvolver told each capture's own model error: the oracle) and `results.csv` (the "
        "exact defocused PSF in the rays, the deconvolver told the sensor's and the render's "
        "noise only; its `psnr_moving_oracle_db` column restores the same captures told their "
        "model error, as before). Same window, sensor, noise target, seeds 0-2 and prior. The "
        "restoration also moved to the sensor's per-pixel noise for hl (as `pacam deconvolve`), "
        "so the exact PSF's shift holds that change too; the oracle's shift is on the same "
        "captures and restoration. At high light the exact PSF moves no camera by more than "
        "the seeds' spread (0.03 dB); the oracle cost the coded camera 0.6-1.0 dB there.",
        "",
        "## Crossing light levels (photons/px/ms, geometric mean over seeds, 95 % interval)",
        "",
        "| coded against | " + " | ".join(n for n, _ in runs) + " |",
        "|---|---|---|---|",
    ]
    for other in ("short", "normal"):
        cells = [_interval([_crossing(r, other, s, lights) for s in SEEDS]) for _, r in runs]
        lines.append(f"| {other} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Moving objects' PSNR (dB, mean over seeds)",
        "",
        "| mode | light | before | oracle (now) | exact PSF's shift | default (now) | "
        "oracle's shift |",
        "|---|---|---|---|---|---|---|",
    ]
    for mode in ("coded", "normal", "short"):
        for x in lights:
            b, o, d = (_mean(r, mode, x) for _, r in runs)
            lines.append(
                f"| {mode} | {x:g} | {b:.2f} | {o:.2f} | {o - b:+.2f} | {d:.2f} | {o - d:+.2f} |"
            )
    (HERE / "rerun.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
