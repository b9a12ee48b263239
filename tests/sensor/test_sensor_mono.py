"""The monochrome ICX285 preset (issue 35 item 5): no Bayer mosaic, and its noise is the
Poisson-Gaussian of the EMVA 1288 linear model, checked against the closed form."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.sensor.apply import check_grey_sensor, is_grey
from pacam_render.sensor.model import SensorModel
from pacam_render.sensor.presets import MONO_PRESETS, available_presets, mono_preset

MONO = "grasshopper-icx285-mono"


def test_mono_preset_is_the_colour_one_without_its_filter():
    colour, mono = SensorModel.from_preset("grasshopper-icx285"), SensorModel.from_preset(MONO)
    assert MONO in available_presets() and MONO_PRESETS["grasshopper-icx285"] == MONO
    assert mono.bayer is None and colour.bayer == "RGGB"
    same = ("read_noise_e", "full_well_e", "dark_current_e_per_s", "K", "bit_depth", "prnu")
    assert all(getattr(mono, k) == getattr(colour, k) for k in same)
    assert colour.qe < mono.qe <= 1.0  # no filter in front of the pixel
    assert mono_preset("grasshopper-icx285") == MONO and mono_preset("paper") == "paper"


def test_mono_noise_matches_the_poisson_gaussian_closed_form():
    """A flat field of p photons, two frames (same fixed pattern, different seeds): the mean is
    K (qe p + dark) + black, and half the variance of their difference is the temporal
    variance K^2 (qe p + dark + read^2) + 1/12 (EMVA 1288's photon transfer). 65 536 pixels:
    the variance's standard error is 0.55 %, the mean's 0.4 DN."""
    m = SensorModel.from_preset(MONO)
    p, t_ms, shape = 10_000.0, 45.0, (256, 256)
    photons = np.full(shape, p)
    a = m.capture(photons, exposure_ms=t_ms, seed=1).astype(np.float64)
    b = m.capture(photons, exposure_ms=t_ms, seed=2).astype(np.float64)
    assert a.shape == shape  # one plane in, one plane out: no mosaic
    signal_e = m.qe * p + m.dark_electrons(t_ms)
    assert a.mean() == pytest.approx(m.K * signal_e + m.black_offset_dn, abs=3.0)
    temporal = np.var(a - b) / 2.0
    closed = m.K**2 * (signal_e + m.read_noise_e**2) + 1.0 / 12.0
    assert temporal == pytest.approx(closed, rel=0.03)
    assert np.sqrt(temporal) / m.K == pytest.approx(
        float(m.temporal_noise_e(m.qe * p, t_ms)), rel=0.02
    )
    # no demosaic: the noise of neighbouring pixels is independent (a bilinear demosaic of a
    # mosaic would correlate them by ~0.5)
    d = a - b
    assert abs(np.corrcoef(d[:, :-1].ravel(), d[:, 1:].ravel())[0, 1]) < 0.02
    lin = m.linear_from_dn(a, p, t_ms)
    assert lin.shape == shape and lin.mean() == pytest.approx(1.0, rel=1e-3)


def test_a_colour_preset_on_a_grey_capture_names_the_mono_one():
    colour = SensorModel.from_preset("grasshopper-icx285")
    assert is_grey(np.zeros((4, 5))) and is_grey(np.zeros((4, 5, 1)))
    assert not is_grey(np.zeros((4, 5, 3)))
    with pytest.raises(ParameterError, match=f"grey.*`sensor` {MONO}"):
        check_grey_sensor(True, colour, "grasshopper-icx285")
    check_grey_sensor(False, colour, "grasshopper-icx285")  # a colour capture: fine
    check_grey_sensor(True, SensorModel.from_preset(MONO), MONO)
    check_grey_sensor(True, SensorModel.from_preset("paper"), "paper")  # no filter either
