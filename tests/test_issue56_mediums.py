"""Issue 56's medium findings: inputs taken or refused wrongly, each against a reference worked
out here.

Item 1: at 0.1 or 0.01 photons/px/ms the noisy layer's mean (less the sensor's offset and read
noise) can be negative, and the noise sigma was taken there: "signal_e must be >= 0". Reference:
the EMVA 1288 sigma at the noise-free capture's mean, written out from the preset's numbers.
Light levels of 1e308 and 1e-300 overflowed with RuntimeWarnings; they are refused in one line
naming light_level (--light-level on the command line) and the range.
"""

from __future__ import annotations

import copy
import math
import warnings

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.limits import PacamWarning
from pacam_render.sensor.apply import add_sensor_layers
from pacam_render.sensor.model import SensorModel

pytestmark = pytest.mark.render

SENSOR = "grasshopper-icx285"


@pytest.fixture(scope="module")
def small_capture():
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=32, height=24, spp=2, seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)
        return render_capture(spec, progress=False, truth=False)


def _expected_sigma(cap, model: SensorModel, light: float) -> float:
    """sqrt(read^2 + quantisation + signal + dark) e- over white's e-, in the capture's units."""
    rec = cap.record
    e_white = model.qe * rec.light_factor * light * rec.reference_exposure_ms
    signal = float(np.mean(cap.image)) / rec.light_factor * e_white
    dark = model.dark_current_e_per_s * rec.exposure_ms * 1e-3
    var = model.read_noise_e**2 + 1 / (12 * model.K**2) + signal + dark
    return math.sqrt(var) / e_white * rec.light_factor


@pytest.mark.parametrize("light", [0.1, 0.01, 1e-6, 1e9])
def test_low_and_high_light_levels_give_the_sensor_noise_at_the_noise_free_level(
    small_capture, light
):
    cap = copy.deepcopy(small_capture)
    model = SensorModel.from_preset(SENSOR)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        warnings.simplefilter("ignore", PacamWarning)  # 1e9 saturates: a note
        add_sensor_layers(cap, model, SENSOR, light, seed=5)
    assert cap.record.noise_sigma == pytest.approx(_expected_sigma(cap, model, light), rel=1e-6)
    assert np.isfinite(cap.extra_layers["noisy"]).all()


@pytest.mark.parametrize("light", [1e308, 1e-300, 0.0])
def test_an_absurd_light_level_is_refused_naming_it_and_the_range(small_capture, light):
    cap = copy.deepcopy(small_capture)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(ParameterError, match=r"light_level must be in \[1e-06, 1e\+09\]"):
            add_sensor_layers(cap, SensorModel.from_preset(SENSOR), SENSOR, light, seed=5)
    assert "noisy" not in cap.extra_layers


@pytest.mark.parametrize("light", ["1e308", "1e-300"])
def test_the_cli_refuses_an_absurd_light_level_in_one_line_before_rendering(
    tmp_path, capsys, light
):
    out = tmp_path / "never"
    argv = ["render", "train", "--sensor", SENSOR, "--light-level", light, "--out", str(out)]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "--light-level must be in [1e-06, 1e+09] photons/px/ms" in err
    assert not out.exists()
