"""Issue 26's probes 7-10 and 12 (and two of its "Low" items), one test each: bad input is
refused before any work, with an error naming the parameter or flag and its range."""

from __future__ import annotations

import json

import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.sensor.model import SensorModel


def _no_render(monkeypatch):
    """Make any capture render fail loudly: the refusals below must come before one."""
    import pacam_render.exposure.capture as capture

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before refusing")

    monkeypatch.setattr(capture, "render_capture", refuse)


# --- 7. extreme sensor presets -------------------------------------------------------------------
@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("K", 1e-308, r"K must be in \[1e-06, 1e\+06\] DN/e-"),
        ("read_noise_e", 1e308, r"read_noise_e must be in \[0, 1e\+06\] e-"),
        ("full_well_e", 1e-300, r"full_well_e must be in \[1, 1e\+09\] e-"),
        ("dsnu_e", 1e300, r"dsnu_e must be in \[0, 1e\+06\] e-"),
        ("dark_current_e_per_s", 1e300, r"dark_current_e_per_s must be in \[0, 1e\+09\] e-/s"),
    ],
)
def test_extreme_sensor_parameters_are_refused_with_their_range(key, value, match):
    with pytest.raises(ParameterError, match=match):
        SensorModel.from_preset("grasshopper-icx285", **{key: value})


def test_an_extreme_preset_file_is_refused_before_the_render(tmp_path, capsys, monkeypatch):
    preset = tmp_path / "odd.json"
    preset.write_text(json.dumps({"base": "grasshopper-icx285", "K": 1e-308}))
    _no_render(monkeypatch)
    out = tmp_path / "out"
    argv = ["render", "train", "--width", "16", "--height", "12", "--spp", "1"]
    assert main([*argv, "--sensor", str(preset), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"preset file {preset}: K must be in [1e-06, 1e+06] DN/e-" in err
    assert not out.exists()
