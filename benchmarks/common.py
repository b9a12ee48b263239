"""Shared plumbing for benchmarks: timing, and printing + recording a results table.

Every benchmark prints its table and records it, with the command, the machine and the date, in
``benchmarks/RESULTS.md`` (override with PACAM_BENCH_RESULTS). Each ``## title`` there holds the
latest run of that table: a rerun replaces its section in place, and the section it replaces moves
to ``archive/RESULTS-<YYYY-MM>.md`` next to the results file (the month of the old run's date).
Earlier runs are in that archive and in git.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import re
import statistics
import sys
import tempfile
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


def parse_sections(text: str) -> tuple[str, list[tuple[str, str]]]:
    """Split a RESULTS.md text into its preamble and its ``(title, text)`` sections.

    A section starts at a line ``## title`` and runs to the next line that starts with ``## ``;
    the text before the first section is the preamble. Preamble and section texts, joined, give
    back the text.
    """
    preamble: list[str] = []
    sections: list[tuple[str, list[str]]] = []
    for line in text.splitlines(keepends=True):
        if line.startswith("## "):
            sections.append((line[3:].strip(), [line]))
        elif sections:
            sections[-1][1].append(line)
        else:
            preamble.append(line)
    return "".join(preamble), [(title, "".join(lines)) for title, lines in sections]


def _write_atomic(path: Path, text: str) -> None:
    """Write text to path through a temporary file in the same folder and os.replace."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _append_block(text: str, block: str) -> str:
    """text, then a blank line, then block (stripped of its surrounding blank lines)."""
    if text and not text.endswith("\n"):
        text += "\n"
    if text.strip() and not text.endswith("\n\n"):
        text += "\n"
    return text + block.strip("\n") + "\n"


def section_month(section: str) -> str:
    """``YYYY-MM`` of a section's ``- date:`` line, or of now (UTC) when it has none."""
    for line in section.splitlines():
        m = re.match(r"- date:\s*(\d{4})-(\d{2})", line)
        if m:
            return f"{m[1]}-{m[2]}"
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m")


def archive_sections(sections: Sequence[str], archive_dir: Path) -> list[Path]:
    """Append sections to ``archive_dir/RESULTS-<YYYY-MM>.md`` by their own month; return the files.

    A new archive file starts with a one-line header. Each file is written atomically.
    """
    by_month: dict[str, list[str]] = {}
    for section in sections:
        by_month.setdefault(section_month(section), []).append(section)
    archive_dir.mkdir(parents=True, exist_ok=True)
    files = []
    for month, old in by_month.items():
        path = archive_dir / f"RESULTS-{month}.md"
        if path.exists():
            text = path.read_text(encoding="utf-8")
        else:
            text = f"# Benchmark runs of {month}, each replaced in the results by a later run\n"
        for section in old:
            text = _append_block(text, section)
        _write_atomic(path, text)
        files.append(path)
    return files


def replace_section(block: str, results: Path, archive_dir: Path | None = None) -> list[str]:
    """Put block, one ``## title`` section, in results in place of the sections of that title.

    The first section with exactly that title is replaced where it stands (any later ones are
    removed); with none, block is appended at the end. The replaced sections are appended to the
    archive (``archive_dir``, by default ``archive/`` next to results) and returned.
    """
    head, new = parse_sections(block.lstrip("\n"))
    if head.strip() or len(new) != 1:
        raise ValueError("block must be exactly one '## title' section")
    title = new[0][0]
    results = Path(results)
    text = results.read_text(encoding="utf-8") if results.exists() else ""
    preamble, sections = parse_sections(text)
    old = [body for t, body in sections if t == title]
    if not old:
        _write_atomic(results, _append_block(text, block))
        return []
    out = preamble
    placed = False
    for t, body in sections:
        if t != title:
            out += body
        elif not placed:  # in place, keeping the blank lines that followed the old section
            trailing = body[len(body.rstrip("\n")) :]
            out += block.strip("\n") + (trailing if len(trailing) > 1 else "\n")
            placed = True
    archive_sections(old, results.parent / "archive" if archive_dir is None else archive_dir)
    _write_atomic(results, out)
    return old


def record(title: str, rows: Sequence[dict], notes: str = "") -> str:
    """Print a results table and record it in RESULTS.md, replacing that title's previous run.

    The previous run's section goes to ``archive/`` next to RESULTS.md; return the Markdown
    block.
    """
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
    replace_section(block, Path(RESULTS))
    return block
