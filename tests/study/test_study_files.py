"""A study cannot crash on its own files (issue 37 items 6, 8 and 15), without rendering.

- results.csv: a row edited by hand (swapped PSNRs, a changed seed) or damaged (``abc`` in a
  number, ``nan`` PSNR in an ``ok`` row) is not taken as done; its point runs again with a
  note, and the report reads such a file without a traceback.
- The study TOML: not UTF-8 is a one-line error naming the file and the byte; a UTF-8
  byte-order mark is read (tomllib alone says "Invalid statement (at line 1, column 1)").
On main before the fix each of these was a traceback, or the edited row was kept.
"""

from __future__ import annotations

import csv
import warnings

import pytest

from pacam_render.errors import ParameterError
from pacam_render.limits import PacamWarning
from pacam_render.study import load_study
from pacam_render.study.point import point_row
from pacam_render.study.report import load_rows
from pacam_render.study.results import Results, row_digest, row_is_intact

TINY = """
[study]
name = "files"
report = "crossover"
[render]
width = 48
height = 36
spp = 4
[grid]
mode = ["coded", "short"]
light_level = [30.0, 3000.0]
"""


@pytest.fixture
def folder(tmp_path):
    """A study folder whose 4 points all finished ok, as the study writes them."""
    path = tmp_path / "s.toml"
    path.write_text(TINY)
    spec = load_study(str(path))
    out = tmp_path / "out"
    out.mkdir()
    res = Results(out, spec)
    values = {"psnr_db": 20.0, "ssim": 0.5}
    res.add([point_row(p, {**values, "psnr_db": 20.0 + p.index}, "ok", 1.0, 2.0)
             for p in spec.points])  # fmt: skip
    return spec, out


def _edit(out, point: int, **cells) -> None:
    path = out / "results.csv"
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        fields, rows = reader.fieldnames, list(reader)
    for r in rows:
        if int(r["point"]) == point:
            r.update({k: str(v) for k, v in cells.items()})
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def _resume(spec, out) -> tuple[set[int], list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PacamWarning)
        done = Results(out, spec).done()
    return done, [str(w.message) for w in caught]


def test_an_untouched_folder_resumes_whole(folder):
    spec, out = folder
    done, notes = _resume(spec, out)
    assert done == {0, 1, 2, 3} and not notes


@pytest.mark.parametrize(
    "cells",
    [
        {"psnr_db": "abc"},  # a non-numeric cell: a traceback at the report stage on main
        {"psnr_db": "nan"},  # accepted as done on main
        {"psnr_db": "25.0"},  # a changed number, digest kept: kept on main
        {"seed": "7"},
    ],
)
def test_an_edited_or_damaged_row_runs_again_with_a_note(folder, cells):
    spec, out = folder
    _edit(out, 2, **cells)
    done, notes = _resume(spec, out)
    assert done == {0, 1, 3}
    assert any("not what the study wrote" in n and "point(s) 2" in n for n in notes)


def test_the_report_reads_a_damaged_file(folder):
    _, out = folder
    _edit(out, 1, psnr_db="abc", ssim="")
    rows = load_rows(out)
    assert [r["psnr_db"] == r["psnr_db"] for r in rows] == [True, False, True, True]  # nan


def test_rows_without_digests_are_checked_by_their_numbers():
    ok = {"status": "ok", "psnr_db": "20", "ssim": "0.5", "render_s": "1", "total_s": "2"}
    assert row_is_intact(ok)
    assert not row_is_intact({**ok, "psnr_db": "inf"})
    assert not row_is_intact({**ok, "ssim": "x"})
    assert row_is_intact({"status": "error: boom", "psnr_db": "abc"})
    assert row_is_intact({**ok, "row_digest": row_digest(ok)})
    assert not row_is_intact({**ok, "row_digest": "0" * 16})


def test_a_study_file_that_is_not_utf8_is_named(tmp_path):
    path = tmp_path / "latin.toml"
    path.write_bytes(TINY.replace("files", "caf\xe9").encode("latin-1"))
    with pytest.raises(ParameterError, match=r"latin.toml.* is not UTF-8 text: byte 0xe9"):
        load_study(str(path))


def test_a_study_file_with_a_byte_order_mark_is_read(tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + TINY.encode())
    assert load_study(str(path)).name == "files"


def test_design_files_are_read_beside_the_study_file(tmp_path, monkeypatch):
    """Issue 47 (low): a study's design paths resolved against the working directory, so a
    study run from elsewhere could not find the design file beside it."""
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import write_design

    sub = tmp_path / "sub"
    sub.mkdir()
    write_design(sub / "mine.toml", prototype().with_(n_patterns=8))
    (sub / "s.toml").write_text(
        '[render]\nscene = "train"\n[grid]\nmode = ["coded"]\n'
        'design = ["prototype", "mine.toml"]\n[[points]]\nmode = "coded"\n'
        'design = "design=mine.toml"\n'
    )
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)
        spec = load_study("sub/s.toml")
    designs = {p.design for p in spec.points}
    assert designs == {"prototype", "sub/mine.toml", "design=sub/mine.toml"}
    monkeypatch.chdir(sub)  # from the study's own folder the text is unchanged
    assert {p.design for p in load_study("s.toml").points} >= {"mine.toml"}
    (tmp_path / "only_here.toml").write_text((sub / "mine.toml").read_text())
    (sub / "t.toml").write_text('[grid]\nmode = ["coded"]\ndesign = ["only_here.toml"]\n')
    monkeypatch.chdir(tmp_path)  # found only from the working directory: taken, with a note
    with pytest.warns(PacamWarning, match="not beside the study file"):
        assert load_study("sub/t.toml").points[0].design == "only_here.toml"
