"""Issue 46's low and medium items with a code fix: each test fails on the main before it."""

from __future__ import annotations

import pytest

from pacam_render.errors import ParameterError


def test_write_capture_takes_a_str_folder_and_refuses_by_default(tmp_path):
    from pacam_render.exposure.capture import render_capture, write_capture
    from pacam_render.exposure.capture_spec import CaptureSpec

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
