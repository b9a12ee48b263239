"""Issue 46's low and medium items with a code fix: each test fails on the main before it."""

from __future__ import annotations

import pytest

from pacam_render.errors import ParameterError


def test_write_capture_takes_a_str_folder_and_refuses_by_default(tmp_path):
    from pacam_render.exposure.direct import render_capture, write_capture
    from pacam_render.exposure.spec import CaptureSpec

    spec = CaptureSpec.geometric(scene="train", width=32, height=24, mode="reference", spp=4)
    cap = render_capture(spec, progress=False, truth=False)
    paths = write_capture(cap, str(tmp_path / "dir"))  # a str, no force: as a user writes it
    assert [p.name for p in paths] == ["capture.exr", "capture.png", "capture.json"]
    with pytest.raises(ParameterError):
        write_capture(cap, str(tmp_path / "dir"))  # never overwrites without force


def test_a_study_estimate_under_an_hour_is_not_zero_hours():
    from pacam_render.study import _check_budget

    with pytest.raises(ParameterError, match=r"about 30 s \("):
        _check_budget(30.0, 0.001)


def test_a_design_files_errors_name_its_keys_not_the_flags(tmp_path, capsys):
    """Issue 46, item 7: a hand-edited design file is refused in its own words (exposure_ms,
    f_number), where the command line's names (--exposure, --f-number) used to appear."""
    from pacam_render.cli import main

    path = tmp_path / "d.toml"
    assert main(["design", "--write", str(path)]) == 0
    text = path.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("n_patterns = 16", "n_patterns = 16\nshutter = 3"))
    assert main(["design", "--design", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "['shutter']; valid: ['exposure_ms', 'n_patterns']" in err and "--exposure" not in err
    bad.write_text(text.replace("[opening]\n", "[opening]\nf_number = 9\n"))
    assert main(["render", "train", "--design", str(bad), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "exactly one of R_mm, f_number, r_px" in err and "--f-number" not in err


def test_the_design_report_cites_the_paper_only_for_the_papers_values():
    """A design file's or a solved design's values are its own, not "Table 1 / Sec. 4", and
    its focus is not "not published"; the prototype's report keeps both."""
    from pacam_render.model.camera import prototype
    from pacam_render.model.report import design_report

    mine = prototype().with_(exposure_ms=20.0, n_patterns=8, object_depth_mm=800.0, R_mm=2.5)
    text = design_report(mine)
    rows = {line.split("  ")[0].strip(): line.rstrip() for line in text.splitlines()}
    assert rows["object depth"].endswith("this design")
    assert rows["exposure"].endswith("this design")
    assert rows["field of view (horizontal)"].endswith("Table 1")  # the paper's 46 deg
    assert "Focus is not published" not in text and "Focus: Z_f =" in text
    proto = design_report(prototype())
    assert "Focus is not published" in proto and "this design" not in proto


def test_a_hand_edited_design_file_is_noted_once(tmp_path):
    """The digest pacam design writes in the header went stale after a hand edit, silently."""
    import warnings

    from pacam_render.limits import PacamWarning
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import read_design, write_design

    p = tmp_path / "d.toml"
    write_design(p, prototype())
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)
        read_design(p)  # as written: nothing to say
    p.write_text(p.read_text().replace("depth_mm = 500.0", "depth_mm = 520.0"))
    with pytest.warns(PacamWarning, match="was edited after pacam design wrote it") as caught:
        cam = read_design(p)
        read_design(p)
    assert len(caught) == 1 and cam.digest() in str(caught[0].message)


def test_getting_started_shows_the_design_report_as_it_is():
    """Issue 46: the report in Getting started lacked the rows the report now prints."""
    from pathlib import Path

    from pacam_render.model.camera import prototype
    from pacam_render.model.report import design_report

    text = (Path(__file__).resolve().parents[1] / "docs" / "getting_started.md").read_text()
    start = text.index("```text\npacam_render design report: prototype")
    block = text[start + len("```text\n") : text.index("```", start + 8)]
    assert block == design_report(prototype()) + "\n"
