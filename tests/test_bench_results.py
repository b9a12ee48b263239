"""Issue 55 item 6: benchmarks/RESULTS.md holds each benchmark once, at its latest run.

A rerun of a benchmark replaces its ``## title`` section in place and moves the old section to
``archive/RESULTS-<YYYY-MM>.md`` next to the results file. The expectations here are written out
by hand (section counts, which block sits where), and the check of the real RESULTS.md reads its
headings with its own few lines, not with ``benchmarks/common.py``'s parser.
"""

from __future__ import annotations

import datetime as dt
import importlib.util
import os
import re

import pytest

ROOT = os.path.join(os.path.dirname(__file__), "..")
RESULTS_MD = os.path.join(ROOT, "benchmarks", "RESULTS.md")

# Sections of the real RESULTS.md recorded without a "- command:" or "- date:" line, and why.
# Empty: every section there was written by common.record, which writes both.
KNOWN_WITHOUT_COMMAND_OR_DATE: set[str] = set()


@pytest.fixture(scope="module")
def common():
    path = os.path.join(ROOT, "benchmarks", "common.py")
    spec = importlib.util.spec_from_file_location("bench_common_under_test", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _block(title: str, date: str, value: str) -> str:
    return (
        f"\n## {title}\n\n- command: `python bench_x.py`\n- machine: test\n- date: {date}\n\n"
        f"| a |\n|---|\n| {value} |\n"
    )


def _headings(text: str) -> list[str]:
    return [line[3:].strip() for line in text.splitlines() if line.startswith("## ")]


def test_a_rerun_replaces_its_section_in_place_and_archives_the_old_one(common, tmp_path):
    results = tmp_path / "RESULTS.md"
    results.write_text("Latest run of each benchmark.\n", encoding="utf-8")
    common.replace_section(_block("Speed (issue 1)", "2026-10-30 09:00 UTC", "first"), results)
    common.replace_section(_block("Quality", "2026-11-01 10:00 UTC", "other"), results)
    assert not (tmp_path / "archive").exists()  # nothing replaced yet

    old = common.replace_section(
        _block("Speed (issue 1)", "2026-11-02 11:00 UTC", "second"), results
    )

    text = results.read_text(encoding="utf-8")
    assert text.startswith("Latest run of each benchmark.\n")
    assert _headings(text) == ["Speed (issue 1)", "Quality"]  # in place, not moved to the end
    assert "| second |" in text and "| first |" not in text and "| other |" in text
    assert len(old) == 1 and "| first |" in old[0]
    # the old run's own month (October), not the month it was replaced in
    archive = tmp_path / "archive" / "RESULTS-2026-10.md"
    assert sorted(p.name for p in (tmp_path / "archive").iterdir()) == [archive.name]
    archived = archive.read_text(encoding="utf-8")
    assert archived.splitlines()[0].startswith("# ")  # a one-line header
    assert _headings(archived) == ["Speed (issue 1)"]
    assert "| first |" in archived and "2026-10-30 09:00 UTC" in archived
    assert not list(tmp_path.glob(".*.tmp")) and not list(archive.parent.glob(".*.tmp"))

    # a third run of the same title: still one section; the archive file grows
    common.replace_section(_block("Speed (issue 1)", "2026-11-03 12:00 UTC", "third"), results)
    text = results.read_text(encoding="utf-8")
    assert _headings(text) == ["Speed (issue 1)", "Quality"] and "| third |" in text
    november = (tmp_path / "archive" / "RESULTS-2026-11.md").read_text(encoding="utf-8")
    assert _headings(november) == ["Speed (issue 1)"] and "| second |" in november
    assert "| first |" in archive.read_text(encoding="utf-8")


def test_titles_are_exact_and_a_section_without_a_date_archives_to_this_month(common, tmp_path):
    results = tmp_path / "RESULTS.md"
    results.write_text("\n## Speed\n\nhand-written, no date\n", encoding="utf-8")
    common.replace_section(_block("Speed (issue 2)", "2026-11-02 11:00 UTC", "new"), results)
    assert _headings(results.read_text(encoding="utf-8")) == ["Speed", "Speed (issue 2)"]
    assert not (tmp_path / "archive").exists()

    common.replace_section(_block("Speed", "2026-11-02 11:00 UTC", "dated"), results)
    month = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m")
    assert "hand-written" in (tmp_path / "archive" / f"RESULTS-{month}.md").read_text()
    assert "hand-written" not in results.read_text(encoding="utf-8")


def test_record_writes_to_the_results_path_and_replaces_its_own_title(
    common, tmp_path, monkeypatch
):
    results = tmp_path / "out" / "RESULTS.md"
    results.parent.mkdir()
    monkeypatch.setattr(common, "RESULTS", results)
    common.record("T one", [{"x": 1.0}])
    common.record("T two", [{"x": 2.0}])
    common.record("T one", [{"x": 3.0}], notes="rerun")
    text = results.read_text(encoding="utf-8")
    assert _headings(text) == ["T one", "T two"]
    assert "| 3 |" in text and "| 1 |" not in text and "- notes: rerun" in text
    (archived,) = (tmp_path / "out" / "archive").iterdir()
    assert "| 1 |" in archived.read_text(encoding="utf-8")


def test_parse_sections_gives_back_the_text(common):
    text = "pre\n\n## A\n\nx\n### sub\n\n## B (issue 3)\ny"
    preamble, sections = common.parse_sections(text)
    assert preamble == "pre\n\n"
    assert [t for t, _ in sections] == ["A", "B (issue 3)"]
    assert sections[0][1] == "## A\n\nx\n### sub\n\n"
    assert preamble + "".join(b for _, b in sections) == text


def _benchmark(title: str) -> str:
    """A title without its trailing "(issue ...)" or "(issues ...)": the same benchmark."""
    return re.sub(r"\s*\(issues? [^()]*\)\s*$", "", title)


def test_the_repository_results_hold_each_benchmark_once_with_its_command_and_date():
    with open(RESULTS_MD, encoding="utf-8") as fh:
        lines = fh.read().splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith("## ")]
    assert len(starts) > 50
    titles = [lines[i][3:].strip() for i in starts]
    seen: dict[str, str] = {}
    for title in titles:
        assert _benchmark(title) not in seen, f"{title!r} repeats {seen[_benchmark(title)]!r}"
        seen[_benchmark(title)] = title
    missing = []
    for i, title in zip(starts, titles):
        body = lines[i + 1 : next((j for j in starts if j > i), len(lines))]
        has = {key for key in ("- command:", "- date:") if any(b.startswith(key) for b in body)}
        if len(has) < 2:
            missing.append(title)
    assert set(missing) == KNOWN_WITHOUT_COMMAND_OR_DATE
