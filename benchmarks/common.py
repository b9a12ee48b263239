"""Shared plumbing for benchmarks: timing, and printing + appending a results table.

Every benchmark prints its table and appends it, with the command, the machine and the date, to
``benchmarks/RESULTS.md`` (override with PACAM_BENCH_RESULTS), so figures accumulate across runs.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

RESULTS = Path(os.environ.get("PACAM_BENCH_RESULTS", Path(__file__).with_name("RESULTS.md")))


def timeit(fn: Callable[[], object], repeat: int = 5, warmup: int = 1) -> list[float]:
    """Wall-clock seconds of ``repeat`` calls of fn, after ``warmup`` untimed calls."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def median_spread(xs: Sequence[float]) -> tuple[float, float]:
    """Median and half the min-max range."""
    return statistics.median(xs), 0.5 * (max(xs) - min(xs))


def machine() -> str:
    """CPU, cores, and the Mitsuba variant when the benchmark rendered anything."""
    variant = ""
    if "mitsuba" in sys.modules:
        variant = sys.modules["mitsuba"].variant() or ""
    cpu = platform.processor() or platform.machine()
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}" + (
        f", {variant}" if variant else ", no rendering"
    )


def _fmt(v: object) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def markdown_table(rows: Sequence[dict]) -> str:
    cols = list(rows[0])
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_fmt(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(lines)


def record(title: str, rows: Sequence[dict], notes: str = "") -> str:
    """Print a results table and append it to RESULTS.md; return the Markdown block."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    cmd = " ".join([Path(sys.argv[0]).as_posix(), *sys.argv[1:]])
    block = (
        f"\n## {title}\n\n- command: `python {cmd}`\n- machine: {machine()}\n- date: {stamp}\n"
        + (f"- notes: {notes}\n" if notes else "")
        + "\n"
        + markdown_table(rows)
        + "\n"
    )
    print(block)
    with open(RESULTS, "a", encoding="utf-8") as fh:
        fh.write(block)
    return block
