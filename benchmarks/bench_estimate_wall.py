"""The printed estimate of a render with a diffraction preview against the command's wall time
(issue 56: the estimate left out the optics budget's kernels and was 2-9x short).

Each case is a fresh ``pacam render`` process (as a user runs it: Python's and Mitsuba's start,
the preview, the capture, the optics budget, the files), timed side by side with the estimate
it prints (``estimate: about ...``, read from its output; its optics part is
:func:`~pacam_render.exposure.optics.cost.optics_seconds`). The history is empty, so the
estimate uses the reference rates
(:data:`~pacam_render.exposure.render_time.REFERENCE_RATES`, fitted on this 2-core machine);
run it on an idle machine.

    python benchmarks/bench_estimate_wall.py
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import record

from pacam_render.render.variant import activate_variant

UNIT_S = {"s": 1.0, "min": 60.0, "h": 3600.0}

CASES = [  # label, CaptureSpec fields, extra CLI flags
    ("coded 160x96 at (400, 500), 128 spp, auto", dict(mode="coded", crop=(400, 500, 160, 96),
     spp=128, diffraction="auto"), []),
    ("normal 160x96 at (400, 500), 128 spp, auto", dict(mode="normal", crop=(400, 500, 160, 96),
     spp=128, diffraction="auto"), []),
    ("coded 320x240 at (300, 400), 64 spp, auto", dict(mode="coded", crop=(300, 400, 320, 240),
     spp=64, diffraction="auto"), []),
    ("coded 160x96, 640x480 sensor, 256 spp, auto", dict(mode="coded", width=640, height=480,
     crop=(200, 250, 160, 96), spp=256, diffraction="auto"), []),
    ("coded 160x96 at (400, 500), 128 spp, on (exact kernels)", dict(mode="coded",
     crop=(400, 500, 160, 96), spp=128, diffraction="on"), []),
]  # fmt: skip


def _flags(fields: dict) -> list[str]:
    x, y, w, h = fields["crop"]
    out = ["--mode", fields["mode"], "--crop", f"{x},{y},{w},{h}", "--spp", str(fields["spp"]),
           "--diffraction", fields["diffraction"]]  # fmt: skip
    if "width" in fields:
        out += ["--width", str(fields["width"]), "--height", str(fields["height"])]
    return out


def _printed(text: str) -> tuple[float, float]:
    """(the estimate's seconds, its optics parts' seconds) from the command's output."""
    line = next(x for x in text.splitlines() if x.startswith("estimate: about"))
    num = r"([0-9.]+(?:e[+-]?[0-9]+)?) (s|min|h)"
    total = re.match(rf"estimate: about {num}", line)
    parts = re.findall(rf"(?:diffraction kernels|diffraction convolutions|exact kernels) {num}",
                       line)  # fmt: skip
    optics = sum(float(v) * UNIT_S[u] for v, u in parts)
    return float(total.group(1)) * UNIT_S[total.group(2)], optics


def main() -> None:
    activate_variant()  # the renders' variant, for the machine line (they run in subprocesses)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        env = {**os.environ, "PACAM_RENDER_TIMES": str(Path(d) / "empty.jsonl")}
        for i, (label, fields, extra) in enumerate(CASES):
            Path(env["PACAM_RENDER_TIMES"]).unlink(missing_ok=True)  # reference rates each time
            cmd = [sys.executable, "-m", "pacam_render", "render", "train", *_flags(fields),
                   *extra, "--out", str(Path(d) / f"c{i}")]  # fmt: skip
            t0 = time.perf_counter()
            run = subprocess.run(cmd, check=True, env=env, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            est, optics = _printed(run.stdout + run.stderr)
            row = {"case": label, "estimate s": est, "of which optics s": optics,
                   "wall s": wall, "wall / estimate": wall / est}  # fmt: skip
            print(row, flush=True)
            rows.append(row)
    ratios = [r["wall / estimate"] for r in rows]
    record(
        "Render estimate with a diffraction preview against the command's wall time (issue 56)",
        rows,
        f"fresh processes, an empty history (the reference rates); wall / estimate "
        f"{min(ratios):.2f}-{max(ratios):.2f} (the target is 0.5-2); the wall adds Python's "
        "and Mitsuba's start (about 2 s) and the files",
    )


if __name__ == "__main__":
    main()
