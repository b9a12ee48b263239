"""The README's five how-to commands, and docs/howto/own_scene.md's, lightfield.md's and
design_on_renders.md's, run as written and print what the documents show (issue 38).

The ``$ ...`` lines of the document's first ``console`` block are run verbatim, in order, in a
fresh folder that holds the repository's ``docs/`` (the commands name
``docs/howto/my_scene.xml``). Each must exit 0, and the lines the document shows after it must
read as the first lines the command printed, numbers aside (timings and Monte Carlo figures
move from run to run). The commands render small windows at 128 spp: about 25 s on 2 cores.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests.doc_blocks import NUMBER, shown_commands

pytestmark = pytest.mark.render

ROOT = Path(__file__).resolve().parents[2]


def console_block(doc: Path) -> list[tuple[str, list[str]]]:
    """(command, the lines the document shows it printing), from its first console block."""
    return shown_commands(doc, "console")


def shape(line: str) -> str:
    """A line with its numbers masked."""
    return NUMBER.sub("#", line)


def run_document(doc: Path, cwd: Path) -> list[tuple[str, list[str], list[str]]]:
    (cwd / "docs").symlink_to(ROOT / "docs")
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    printed = []
    for cmd, shown in console_block(doc):
        p = subprocess.run(shlex.split(cmd), cwd=cwd, env=env, capture_output=True, text=True)
        assert p.returncode == 0, f"{cmd}\n{p.stderr}"
        printed.append((cmd, shown, p.stdout.splitlines()))
    return printed


def check(printed) -> None:
    for cmd, shown, out in printed:
        assert shown, f"the document shows no output for {cmd}"
        assert [shape(s) for s in shown] == [shape(o) for o in out[: len(shown)]], cmd


def test_the_readme_how_to_runs_as_written(tmp_path):
    commands = console_block(ROOT / "README.md")
    assert len(commands) == 5
    assert all(c.startswith("pacam ") for c, _ in commands)
    printed = run_document(ROOT / "README.md", tmp_path)
    check(printed)
    for folder in ("caps/coded", "caps/coded300", "caps/mine"):
        assert (tmp_path / folder / "capture.exr").is_file(), folder
    assert (tmp_path / "deblurred" / "deconvolved.json").is_file()


def test_the_own_scene_how_to_runs_as_written(tmp_path):
    printed = run_document(ROOT / "docs" / "howto" / "own_scene.md", tmp_path)
    assert len(printed) == 2
    check(printed)
    assert (tmp_path / "caps" / "mine-deblurred" / "deconvolved.json").is_file()


def test_the_readme_fits_on_a_few_screens():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 250


def test_the_lightfield_how_to_runs_as_written(tmp_path):
    """docs/howto/lightfield.md: a store, then three designs' captures from it."""
    printed = run_document(ROOT / "docs" / "howto" / "lightfield.md", tmp_path)
    assert len(printed) == 4
    check(printed)
    for name in ("coded", "cover1.4", "normal"):
        assert (tmp_path / "caps" / name / "capture.exr").is_file(), name


def test_the_design_on_renders_how_to_runs_as_written(tmp_path):
    """docs/howto/design_on_renders.md: two stores, then a search on them, checked."""
    printed = run_document(ROOT / "docs" / "howto" / "design_on_renders.md", tmp_path)
    assert len(printed) == 3
    check(printed)
    assert (tmp_path / "designed" / "design.toml").is_file()
