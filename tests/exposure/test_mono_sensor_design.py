"""A design's sensor decides its channels (issue 46, trap 3): a monochrome sensor in a design
file, or as ``--sensor``, renders one channel without ``--grey``; a monochrome sensor on an
RGB capture is refused, naming the fix (its noise model would be drawn per channel)."""

from __future__ import annotations

import json

import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model.camera import prototype
from pacam_render.model.design_file import write_design

MONO = "grasshopper-icx285-mono"
WINDOW = ["--crop", "456,410,48,32", "--spp", "4", "--diffraction", "off", "--quiet"]


def _mono_design(tmp_path):
    path = tmp_path / "mono.toml"
    write_design(path, prototype().with_(sensor_preset=MONO))
    return str(path)


def test_a_mono_design_file_plans_a_grey_capture_in_the_api(tmp_path):
    spec = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(456, 410, 48, 32),
                       design=_mono_design(tmp_path))  # fmt: skip
    plan = plan_capture(spec)  # its notes are kept, and said again by the capture
    assert plan.spec.grey and "mono" in plan.variant
    assert any("monochrome: the capture renders one channel" in n for n in plan.notes)
    colour = plan_capture(CaptureSpec.geometric(scene="train", width=1280, height=960))
    assert not colour.spec.grey  # a preset without a sensor stays RGB


@pytest.mark.render
@pytest.mark.parametrize("how", ["design", "flag"])
def test_a_mono_sensor_renders_one_channel_without_grey(tmp_path, capsys, how):
    extra = ["--design", _mono_design(tmp_path)] if how == "design" else ["--sensor", MONO]
    out = tmp_path / "cap"
    assert main(["render", "train", *WINDOW, *extra, "--out", str(out)]) == 0
    meta = json.loads((out / "capture.json").read_text())
    assert meta["spec"]["grey"] is True
    assert meta["sensor"]["preset"] == MONO
    assert "renders one channel" in capsys.readouterr().err


@pytest.mark.render
def test_a_mono_sensor_on_an_rgb_capture_is_refused(tmp_path, capsys):
    out = tmp_path / "rgb"
    assert main(["render", "train", *WINDOW, "--out", str(out)]) == 0
    assert main(["sensor", str(out / "capture.exr"), "--sensor", MONO, "--out",
                 str(tmp_path / "s")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "monochrome" in err and "grey" in err and "Traceback" not in err
    from pacam_render.sensor.apply import check_grey_sensor
    from pacam_render.sensor.model import SensorModel

    with pytest.raises(ParameterError, match="monochrome"):
        check_grey_sensor(False, SensorModel.from_preset(MONO), MONO)
