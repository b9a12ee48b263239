"""Grey studies (issue 35 item 5): ``grey = true`` in ``[render]`` (``pacam study --grey``)
renders every capture with the mono variant, swaps the built-in colour sensor for its
monochrome twin, and scores one channel."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.render.variant import llvm_status
from pacam_render.study import load_study
from pacam_render.study.point import Task, capture_inputs, run_task
from pacam_render.study.spec import parse_study

MONO = "grasshopper-icx285-mono"
TINY = {
    "study": {"name": "tiny-grey"},
    "render": {"width": 32, "height": 24, "spp": 8, "noise_ratio": False, "max_step_px": 4.0},
    "grid": {"mode": ["coded"], "light_level": [3000.0], "method": ["hl"]},
}


def test_grey_key_and_flag_give_the_mono_sensor_and_keep_colour_keys():
    colour = parse_study(TINY)
    grey = parse_study({**TINY, "render": {**TINY["render"], "grey": True}})
    flag = parse_study(TINY, grey=True)
    assert "grey" not in colour.render and colour.points[0].sensor == "grasshopper-icx285"
    assert grey.render["grey"] is True and grey.points[0].sensor == MONO
    assert flag.key() == grey.key() != colour.key()
    off = parse_study({**TINY, "render": {**TINY["render"], "grey": False}})
    assert off.key() == colour.key()  # false is the default: the same study
    spec, _, _ = capture_inputs(grey.render, grey.points[0])
    assert spec.grey is True
    quick = load_study("crossover", quick=True, grey=True)
    assert {p.sensor for p in quick.points} == {MONO} and quick.render["grey"] is True


def test_bad_grey_values_are_refused(tmp_path, monkeypatch):
    with pytest.raises(ParameterError, match=r"\[render\] grey must be true or false"):
        parse_study({**TINY, "render": {**TINY["render"], "grey": "yes"}})
    bayer = tmp_path / "bayer.json"
    bayer.write_text(json.dumps({"base": "grasshopper-icx285"}))
    doc = {**TINY, "grid": {**TINY["grid"], "sensor": [str(bayer)]}}
    with pytest.raises(ParameterError, match="colour filter array.*grasshopper-icx285-mono"):
        parse_study(doc, grey=True)
    monkeypatch.setenv("PACAM_VARIANT", "llvm_ad_rgb")
    with pytest.raises(ParameterError, match="PACAM_VARIANT='llvm_ad_rgb' renders colour"):
        parse_study(TINY, grey=True)


@pytest.mark.render
def test_a_grey_point_renders_and_scores():
    """One grey point end to end in this process: on main the model error and the score
    indexed the third axis of a grey image and the point failed."""
    import mitsuba as mi

    ok, why = llvm_status()
    if not ok:
        pytest.skip(f"needs the LLVM backend: {why}")
    spec = parse_study(TINY, grey=True)
    before = mi.variant()
    try:
        (row,) = run_task(Task(spec.render, spec.points))
    finally:
        if before is not None:
            mi.set_variant(before)
    assert row["status"] == "ok", row["status"]
    assert row["sensor"] == MONO and np.isfinite(row["psnr_db"]) and 0 < row["ssim"] <= 1
    assert np.isfinite(row["model_sigma"]) and row["noise_sigma"] > 0
