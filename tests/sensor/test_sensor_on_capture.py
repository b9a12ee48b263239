"""The image sensor on a capture already on disk (issue 27 item 6): what ``render --sensor``
gives, bit for bit with the capture's seed and in distribution with another."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture, write_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.limits import PacamWarning
from pacam_render.sensor.apply import add_sensor_layers
from pacam_render.sensor.model import SensorModel
from pacam_render.sensor.on_capture import load_capture, sensor_on_capture

pytestmark = pytest.mark.render
PRESET, LIGHT = "grasshopper-icx285", 3000.0


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A capture written without a sensor, and the same capture through the sensor in memory
    (what ``render --sensor`` writes)."""
    out = tmp_path_factory.mktemp("plain")
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=64, height=48, spp=8, seed=5)
    with pytest.warns(PacamWarning):
        cap = render_capture(spec, progress=False)
    write_capture(cap, out, force=False)
    add_sensor_layers(cap, SensorModel.from_preset(PRESET), PRESET, LIGHT, spec.seed)
    return out, cap


def test_the_captures_seed_gives_render_sensor_bit_for_bit(rendered):
    out, direct = rendered
    cap = sensor_on_capture(out, PRESET, LIGHT)
    for k in ("raw", "noisy"):
        np.testing.assert_array_equal(cap.extra_layers[k], direct.extra_layers[k])
    assert cap.record.sensor == direct.record.sensor
    assert cap.record.noise_sigma == direct.record.noise_sigma
    ratio = cap.record.render_error.ratio_to_sensor
    assert ratio == pytest.approx(direct.record.render_error.ratio_to_sensor)


def test_another_seed_gives_the_same_noise_in_distribution(rendered):
    """Residuals noisy - capture of two seeds: the same sigma within 5 % and the same mean
    within 5 standard errors (9216 values each), but not the same draws."""
    out, direct = rendered
    cap = sensor_on_capture(out, PRESET, LIGHT, seed=1)
    a = direct.extra_layers["noisy"] - direct.image
    b = cap.extra_layers["noisy"] - cap.image
    assert b.std() == pytest.approx(a.std(), rel=0.05)
    assert abs(b.mean() - a.mean()) < 5 * a.std() * np.sqrt(2 / a.size)
    assert np.mean(a == b) < 0.5


def test_a_second_sensor_replaces_the_first_with_a_note(rendered, tmp_path):
    out, _ = rendered
    first = tmp_path / "first"
    write_capture(sensor_on_capture(out, PRESET, 300.0), first, force=False)
    with pytest.warns(PacamWarning, match="replaced by"):
        cap = sensor_on_capture(first, PRESET, LIGHT)
    assert cap.record.sensor.light_level_photons_per_px_per_ms == LIGHT
    again = load_capture(first)
    assert again.record.sensor.light_level_photons_per_px_per_ms == 300.0
    assert set(again.extra_layers) >= {"sharp", "depth", "object_id", "velocity", "raw"}


def test_bad_input_is_refused_before_any_work(rendered, tmp_path):
    out, _ = rendered
    with pytest.raises(ParameterError, match="light_level"):
        sensor_on_capture(out, PRESET, -1.0)
    with pytest.raises(ParameterError, match="nope"):
        sensor_on_capture(out, "nope", LIGHT)
    lonely = tmp_path / "lonely"
    lonely.mkdir()
    shutil.copy(out / "capture.exr", lonely / "capture.exr")
    with pytest.raises(ParameterError, match="capture.json beside it"):
        sensor_on_capture(lonely, PRESET, LIGHT)
    (lonely / "capture.json").write_text(json.dumps({"mode": "coded"}))
    with pytest.raises(ParameterError, match="'camera'"):
        sensor_on_capture(lonely, PRESET, LIGHT)
