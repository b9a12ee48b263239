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
