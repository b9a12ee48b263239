"""Sensor model (issue 5) against independent references.

- Peer check: a photon-transfer sweep analysed by ``emva1288`` (the EMVA 1288 reference
  implementation) recovers K, the temporal dark noise and the saturation capacity within 3 %.
- Closed forms: mean and variance of the signal, Poisson at low counts, dark-current shot noise,
  full-well and ADC clipping, quantisation noise 1/12 DN^2.
- Fixed pattern and seeds, presets, Bayer mosaic/demosaic, light levels, and bad input.
"""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from pacam_render.errors import ParameterError
from pacam_render.sensor import bayer
from pacam_render.sensor.model import SensorModel, simulate_capture
from pacam_render.sensor.presets import PRESETS, available_presets
from pacam_render.sensor.radiometry import (
    DEFAULT_LIGHT_LEVEL,
    aperture_area_mm2,
    photons_from_render,
    photons_per_unit,
)

EMVA_NAMES = (
    "qe",
    "dark_current_e_per_s",
    "read_noise_e",
    "full_well_e",
    "K",
    "black_offset_dn",
    "bit_depth",
    "prnu",
    "dsnu_e",
    "bayer",
)


def ideal(**kw) -> SensorModel:
    """A noise-free-by-default model; tests switch on what they check."""
    base = dict(qe=1.0, K=1.0, full_well_e=1e6, bit_depth=24, black_offset_dn=0.0)
    return SensorModel(**{**base, **kw})


# ------------------------------------------------------------------------ EMVA 1288 peer
def _temporal_stats(frames):
    from emva1288.process import routines

    d = routines.get_int_imgs(frames)
    return {"sum": np.sum(d["sum"]), "pvar": np.sum(d["pvar"]), "dmean": d["dmean"]}


def _emva_results(model, rate_photons_per_ms, exposures_ms, shape, seed, n_spatial=8):
    """Simulate an EMVA 1288 exposure-time sweep in memory and run the reference analysis."""
    from emva1288.process import Data1288, Results1288, routines

    seeds = iter(np.random.SeedSequence(seed).generate_state(4 * len(exposures_ms) + 64))
    dark = np.zeros(shape)

    def frames(photons, t, n):
        return [model.capture(photons, exposure_ms=t, seed=int(next(seeds))) for _ in range(n)]

    temporal = {}
    for t in exposures_ms:
        u_p = float(rate_photons_per_ms * t)
        temporal[t * 1e6] = {  # emva1288 wants exposure times in ns
            0.0: _temporal_stats(frames(dark, t, 2)),
            u_p: _temporal_stats(frames(np.full(shape, u_p), t, 2)),
        }
    t_mid = exposures_ms[len(exposures_ms) // 2]
    u_mid = float(rate_photons_per_ms * t_mid)
    spatial = {
        t_mid * 1e6: {
            0.0: routines.get_int_imgs(frames(dark, t_mid, n_spatial)),
            u_mid: routines.get_int_imgs(frames(np.full(shape, u_mid), t_mid, n_spatial)),
        }
    }
    data = {"temporal": temporal, "spatial": spatial, "height": shape[0], "width": shape[1]}
    return Results1288(Data1288(data).data, loglevel=logging.WARNING)


@pytest.fixture
def emva_numpy2(monkeypatch):
    """emva1288 1.0.2 calls np.asfarray, removed in numpy 2.0; shim it for the test only."""
    if not hasattr(np, "asfarray"):
        monkeypatch.setattr(
            np, "asfarray", lambda a, dtype=np.float64: np.asarray(a, dtype), raising=False
        )
    pytest.importorskip("emva1288")


PTC_CASES = {
    # the prototype's CCD without its Bayer filter: K < 1, the ADC clips at 17738 e-
    "icx285": (
        SensorModel.from_preset("grasshopper-icx285", bayer=None),
        900.0,  # photons/px/ms: saturation (35476 photons) near 39 ms
        0.4,  # ms per step
    ),
    # K > 1 and strong dark current; the 16-bit ADC clips at (65535 - 100) / 2 = 32717.5 e-
    "k2-16bit": (
        SensorModel(
            qe=0.7,
            dark_current_e_per_s=2000.0,
            read_noise_e=4.0,
            full_well_e=40000.0,
            K=2.0,
            black_offset_dn=100.0,
            bit_depth=16,
            prnu=0.01,
            dsnu_e=3.0,
            seed=7,
        ),
        4674.0,  # photons/px/ms: saturation near 10 ms
        0.1,
    ),
}


def _expected_emva_saturation_e(model, rate, exposures_ms):
    """Where the model's mean temporal variance peaks on the sweep's grid, in photo-e-.

    EMVA 1288 defines the saturation capacity at the variance maximum, which noise puts a few
    sigma below the noise-free clip. Per pixel the DN is ~ normal (Poisson + read noise, times K)
    clipped at the ADC top; the censored-normal variance is averaged over the PRNU gains
    (Gauss-Hermite quadrature over the log-normal).
    """
    z, w = np.polynomial.hermite_e.hermegauss(40)
    s2 = math.log1p(model.prnu**2)
    gains = np.exp(z * math.sqrt(s2) - s2 / 2)[:, None]
    t = np.asarray(exposures_ms)[None, :]
    mu_e = model.qe * rate * t * gains + model.dark_current_e_per_s * t * 1e-3
    mu = model.K * mu_e + model.black_offset_dn
    sd = model.K * np.sqrt(mu_e + model.read_noise_e**2)
    a = (model.max_dn - mu) / sd
    cdf, pdf = stats.norm.cdf(a), stats.norm.pdf(a)
    m1 = mu * cdf - sd * pdf + model.max_dn * (1 - cdf)
    m2 = (mu**2 + sd**2) * cdf - sd * (mu + model.max_dn) * pdf + model.max_dn**2 * (1 - cdf)
    var = (w[:, None] * (m2 - m1**2)).sum(axis=0) / w.sum()
    return model.qe * rate * exposures_ms[int(np.argmax(var))]


@pytest.mark.parametrize("case", sorted(PTC_CASES))
def test_emva1288_photon_transfer_recovers_parameters(case, emva_numpy2):
    model, rate, step_ms = PTC_CASES[case]
    exposures = [round(step_ms * k, 6) for k in range(1, 111)]  # 1 % .. 110 % of saturation
    res = _emva_results(model, rate, exposures, (256, 256), seed=sorted(PTC_CASES).index(case))

    # truth: temporal dark noise extrapolated to zero exposure (read noise + quantisation)
    sigma_y_dark = math.sqrt((model.K * model.read_noise_e) ** 2 + 1 / 12)
    assert res.K == pytest.approx(model.K, rel=0.03)
    assert res.sigma_y_dark == pytest.approx(sigma_y_dark, rel=0.03)
    assert res.sigma_d == pytest.approx(model.read_noise_e, rel=0.03)
    # saturation capacity as EMVA 1288 defines it (the variance peak), predicted from the
    # model; noise puts it a few sigma below the noise-free clip, saturation_e
    expected = _expected_emva_saturation_e(model, rate, exposures)
    assert res.u_e_sat == pytest.approx(expected, rel=0.03)
    assert 0.95 * model.saturation_e < res.u_e_sat < model.saturation_e
    # beyond the brief, same tolerance: QE, dark current and the fixed pattern
    assert res.QE / 100 == pytest.approx(model.qe, rel=0.03)
    if model.dark_current_e_per_s > 100:
        assert res.u_I_mean == pytest.approx(model.dark_current_e_per_s, rel=0.03)
        assert res.u_I_var == pytest.approx(model.dark_current_e_per_s, rel=0.03)
    assert res.DSNU1288 == pytest.approx(model.dsnu_e, rel=0.05)
    assert res.PRNU1288 / 100 == pytest.approx(model.prnu, rel=0.05)


# ---------------------------------------------------------------------------- closed forms
def test_mean_and_variance_match_closed_form():
    m = ideal(qe=0.6, K=2.5, read_noise_e=3.0, dark_current_e_per_s=5000.0, black_offset_dn=100.0)
    photons = np.full((512, 1024), 500.0)
    dn = m.capture(photons, exposure_ms=20.0, seed=11).astype(np.float64)
    mu_e = 0.6 * 500.0 + 5000.0 * 0.020  # photo + dark electrons
    assert dn.mean() == pytest.approx(2.5 * mu_e + 100.0, abs=0.5)
    # Poisson (photo + dark) + read noise, times K^2, plus quantisation
    var = 2.5**2 * (mu_e + 3.0**2) + 1 / 12
    assert dn.var() == pytest.approx(var, rel=0.01)
    assert (2.5 * m.temporal_noise_e(0.6 * 500.0, 20.0)) ** 2 == pytest.approx(var, rel=1e-12)


def test_quantisation_noise_is_one_twelfth_dn2():
    m = ideal(shot_noise=False, K=0.37)
    photons = np.random.default_rng(5).uniform(100.0, 5000.0, size=1_000_000)
    err = m.capture(photons, seed=0).astype(np.float64) - 0.37 * photons
    assert err.mean() == pytest.approx(0.0, abs=2e-3)
    assert np.abs(err).max() <= 0.5
    assert (err**2).mean() == pytest.approx(1 / 12, rel=0.01)


@pytest.mark.parametrize("mean_e", [0.3, 3.0])
def test_shot_noise_is_exact_poisson_at_low_counts(mean_e):
    m = ideal(qe=0.5)
    n = 1_000_000
    dn = m.capture(np.full(n, 2 * mean_e), seed=3)
    p0 = (dn == 0).mean()
    assert p0 == pytest.approx(math.exp(-mean_e), abs=5 * math.sqrt(math.exp(-mean_e) / n))
    kmax = 12
    observed = np.bincount(np.minimum(dn, kmax), minlength=kmax + 1)
    pmf = stats.poisson.pmf(np.arange(kmax), mean_e)
    expected = n * np.append(pmf, 1 - pmf.sum())
    keep = expected > 5
    obs = np.append(observed[keep], observed[~keep].sum())
    exp = np.append(expected[keep], expected[~keep].sum())
    if exp[-1] == 0:
        obs, exp = obs[:-1], exp[:-1]
    assert stats.chisquare(obs, exp * obs.sum() / exp.sum()).pvalue > 1e-3


def test_dark_current_has_its_own_shot_noise_and_scales_with_exposure():
    m = ideal(dark_current_e_per_s=1000.0)
    dark = np.zeros(400_000)
    for t_ms in (7.0, 14.0):
        dn = m.capture(dark, exposure_ms=t_ms, seed=4).astype(np.float64)
        lam = 1000.0 * t_ms / 1000
        assert dn.mean() == pytest.approx(lam, rel=0.01)
        assert dn.var() == pytest.approx(lam, rel=0.02)  # Poisson: variance = mean
    with pytest.raises(ParameterError, match="exposure_ms is required"):
        m.capture(dark)


def test_full_well_clipping():
    m = ideal(K=0.9, full_well_e=18000.0, black_offset_dn=64.0, bit_depth=14)
    dn = m.capture(np.array([1e5, 1e9, 1e30, 1e300]), seed=1)
    assert np.all(dn == round(0.9 * 18000 + 64))
    noisy = m.replace(read_noise_e=8.0).capture(np.full(100_000, 1e9), seed=2)
    assert noisy.astype(float).mean() == pytest.approx(0.9 * 18000 + 64, abs=0.2)
    assert noisy.astype(float).std() == pytest.approx(0.9 * 8.0, rel=0.02)  # read noise only


def test_adc_clipping_at_both_ends():
    m = ideal(K=2.0, full_well_e=1e5, bit_depth=12, read_noise_e=50.0)
    bright = m.capture(np.full(10_000, 5e4), seed=1)
    assert bright.dtype == np.uint16
    assert np.all(bright == 4095)
    dark = m.capture(np.zeros(100_000), seed=2)
    assert dark.min() == 0
    assert (dark == 0).mean() == pytest.approx(0.5, abs=0.01)  # half the read noise is < 0
    assert m.saturation_e == pytest.approx(4095 / 2.0)


def test_output_dtype_follows_bit_depth():
    assert ideal(bit_depth=16).capture(np.ones(3), seed=0).dtype == np.uint16
    assert ideal(bit_depth=17).capture(np.ones(3), seed=0).dtype == np.uint32
    top = ideal(bit_depth=32, K=1e6, full_well_e=1e6).capture(np.full(2, 1e6), seed=0)
    assert np.all(top == 2**32 - 1)


# -------------------------------------------------------------------- fixed pattern, seeds
def test_same_seeds_bit_identical_and_different_seeds_differ():
    m = SensorModel.from_preset("grasshopper-icx285", bayer=None)
    photons = np.random.default_rng(0).uniform(0, 3e4, (300, 400))
    a = m.capture(photons, exposure_ms=45.0, seed=9)
    b = SensorModel.from_preset("grasshopper-icx285", bayer=None).capture(
        photons, exposure_ms=45.0, seed=9
    )
    assert np.array_equal(a, b)
    assert not np.array_equal(a, m.capture(photons, exposure_ms=45.0, seed=10))
    ss = np.random.SeedSequence(123)  # a reused SeedSequence repeats itself
    assert np.array_equal(
        m.capture(photons, exposure_ms=45.0, seed=ss), m.capture(photons, exposure_ms=45.0, seed=ss)
    )


def test_result_does_not_depend_on_thread_count():
    m = SensorModel.from_preset("grasshopper-icx285", bayer=None)
    photons = np.full((700, 300), 2e4)  # several noise blocks
    one = m.capture(photons, exposure_ms=45.0, seed=5, workers=1)
    two = m.capture(photons, exposure_ms=45.0, seed=5, workers=2)
    assert np.array_equal(one, two)


def test_prnu_is_a_fixed_pattern_with_the_given_spread():
    m = ideal(shot_noise=False, prnu=0.1, seed=1)
    photons = np.full((256, 256), 1e4)
    a = m.capture(photons, seed=1)
    assert np.array_equal(a, m.capture(photons, seed=2))  # not redrawn per frame
    assert np.array_equal(a, ideal(shot_noise=False, prnu=0.1, seed=1).capture(photons, seed=3))
    assert not np.array_equal(a, ideal(shot_noise=False, prnu=0.1, seed=2).capture(photons))
    gain = a / 1e4
    assert gain.mean() == pytest.approx(1.0, abs=2e-3)
    assert gain.std() == pytest.approx(0.1, rel=0.03)
    assert gain.min() > 0


def test_dsnu_is_a_fixed_pattern_with_the_given_spread():
    m = ideal(shot_noise=False, dsnu_e=5.0, black_offset_dn=100.0)
    dark = np.zeros((256, 256))
    a = m.capture(dark, seed=1).astype(np.float64)
    assert np.array_equal(a, m.capture(dark, seed=2))
    assert a.mean() == pytest.approx(100.0, abs=0.1)
    assert a.std() == pytest.approx(math.sqrt(25 + 1 / 12), rel=0.03)


def test_fixed_pattern_is_per_shape_and_cached():
    m = ideal(shot_noise=False, prnu=0.05, dsnu_e=1.0)
    g1, o1 = m.fixed_pattern((8, 8))
    g2, _ = m.fixed_pattern((16, 4))
    assert g1.shape == (8, 8) and g2.shape == (16, 4) and o1.shape == (8, 8)
    assert m.fixed_pattern((8, 8))[0] is g1
    first = m.capture(np.full((8, 8), 100.0), seed=0)
    m.capture(np.full((16, 4), 100.0), seed=0)
    assert np.array_equal(first, m.capture(np.full((8, 8), 100.0), seed=0))
    assert ideal().fixed_pattern((4, 4)) == (None, None)


# ------------------------------------------------------------------------------- presets
def test_emva_attributes_readable_on_every_preset():
    for name in available_presets():
        m = SensorModel.from_preset(name)
        for attr in EMVA_NAMES:
            getattr(m, attr)
        assert isinstance(m.bit_depth, int) and 1 <= m.bit_depth <= 32
        assert 0 < m.qe <= 1 and m.K > 0 and m.full_well_e > 0
        assert m.name == name


def test_grasshopper_preset_values():
    m = SensorModel.from_preset("grasshopper-icx285")
    assert (m.bit_depth, m.bayer, m.full_well_e, m.K) == (14, "RGGB", 18000.0, 0.92)
    assert m.saturation_e == pytest.approx((16383 - 64) / 0.92)  # the ADC clips first
    raw = m.capture(np.full((6, 8, 3), 1e3), exposure_ms=45.0, seed=0)
    assert raw.shape == (6, 8) and raw.dtype == np.uint16


def test_paper_preset_is_gaussian_sigma_on_unit_image():
    m = SensorModel.from_preset("paper")
    assert m.sigma == pytest.approx(0.01)
    x = np.concatenate([np.full(200_000, 0.05), np.full(200_000, 0.95)])
    y = m.unit_from_dn(m.capture(m.photons_from_unit(x), seed=1))
    noise = y - x
    assert noise.mean() == pytest.approx(0.0, abs=1e-4)
    # no shot noise: the same sigma in the dark and in the bright
    assert noise[:200_000].std() == pytest.approx(0.01, rel=0.01)
    assert noise[200_000:].std() == pytest.approx(0.01, rel=0.01)
    assert m.capture(m.photons_from_unit(x[:5]), seed=1).dtype == np.uint32
    level = m.temporal_noise_e(np.array([0.0, 0.5 * m.full_well_e])) / m.full_well_e
    np.testing.assert_allclose(level, 0.01, rtol=1e-6)  # sigma, whatever the signal


def test_paper_sigma_is_settable_and_noise_below_zero_is_kept():
    m = SensorModel.from_preset("paper", sigma=0.05)
    assert m.read_noise_e == pytest.approx(0.05 * 65536)
    y = m.unit_from_dn(m.capture(np.zeros(100_000), seed=2))
    assert y.min() < -0.1 and y.mean() == pytest.approx(0.0, abs=1e-3)
    exact = SensorModel.from_preset("paper", sigma=0.0)
    x = np.random.default_rng(1).uniform(0, 1, 10_000)
    assert np.abs(exact.unit_from_dn(exact.capture(exact.photons_from_unit(x))) - x).max() <= (
        2.0**-17
    )


def test_as_dict_round_trips_through_json(tmp_path):
    for name in available_presets():
        m = SensorModel.from_preset(name)
        assert SensorModel(**json.loads(json.dumps(m.as_dict()))) == m
        path = tmp_path / f"{name}.json"
        path.write_text(json.dumps(m.as_dict()))
        assert SensorModel.from_preset(str(path)).replace(name=name) == m


def test_user_preset_json_and_toml(tmp_path):
    js = tmp_path / "mycam.json"
    js.write_text(json.dumps({"base": "grasshopper-icx285", "K": 0.5, "description": "x"}))
    m = SensorModel.from_preset(str(js))
    assert (m.name, m.K, m.full_well_e, m.bayer) == ("mycam", 0.5, 18000.0, "RGGB")
    tm = tmp_path / "noisy.toml"
    tm.write_text('base = "paper"\nsigma = 0.03\n')
    t = SensorModel.from_file(tm)
    assert t.sigma == pytest.approx(0.03) and t.shot_noise is False
    assert SensorModel.from_preset(str(tm), sigma=0.07).sigma == pytest.approx(0.07)


# --------------------------------------------------------------------------------- Bayer
def test_mosaic_keeps_the_filter_colour():
    rgb = np.broadcast_to(np.array([10.0, 20.0, 30.0]), (4, 6, 3))
    mos = bayer.mosaic(rgb, "RGGB")
    assert np.array_equal(mos[0::2, 0::2], np.full((2, 3), 10.0))
    assert np.array_equal(mos[0::2, 1::2], np.full((2, 3), 20.0))
    assert np.array_equal(mos[1::2, 0::2], np.full((2, 3), 20.0))
    assert np.array_equal(mos[1::2, 1::2], np.full((2, 3), 30.0))
    assert bayer.mosaic(rgb, "BGGR")[0, 0] == 30.0
    assert bayer.mosaic(rgb, "GRBG")[0, 1] == 10.0 and bayer.mosaic(rgb, "GBRG")[0, 1] == 30.0


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(2, 9),
    w=st.integers(2, 9),
    pattern=st.sampled_from(bayer.BAYER_PATTERNS),
    colour=st.tuples(*[st.floats(0, 1e4)] * 3),
    seed=st.integers(0, 2**16),
)
def test_demosaic_keeps_samples_and_constant_colours(h, w, pattern, colour, seed):
    flat = np.broadcast_to(np.array(colour), (h, w, 3))
    out = bayer.demosaic_bilinear(bayer.mosaic(flat, pattern).astype(np.float64), pattern)
    np.testing.assert_allclose(out, flat, rtol=1e-12, atol=1e-9)
    rgb = np.random.default_rng(seed).uniform(0, 1, (h, w, 3))
    mos = bayer.mosaic(rgb, pattern)
    assert np.allclose(bayer.mosaic(bayer.demosaic_bilinear(mos, pattern), pattern), mos)


def _demosaic_by_convolution(raw, pattern):
    """Reference: the textbook bilinear demosaic, 3x3 kernels on each colour's masked plane."""
    from scipy import ndimage

    k_rb = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]]) / 4
    k_g = np.array([[0, 1, 0], [1, 4, 1], [0, 1, 0]]) / 4
    idx = np.tile(bayer.tile_channels(pattern), (raw.shape[0] // 2 + 1, raw.shape[1] // 2 + 1))
    idx = idx[: raw.shape[0], : raw.shape[1]]
    planes = [
        ndimage.convolve(np.where(idx == c, raw, 0.0), k_g if c == 1 else k_rb, mode="mirror")
        for c in range(3)
    ]
    return np.stack(planes, axis=-1)


@settings(max_examples=40, deadline=None)
@given(
    h=st.integers(2, 11),
    w=st.integers(2, 11),
    pattern=st.sampled_from(bayer.BAYER_PATTERNS),
    seed=st.integers(0, 2**16),
)
def test_demosaic_matches_convolution_reference(h, w, pattern, seed):
    raw = np.random.default_rng(seed).uniform(0, 1e4, (h, w))
    np.testing.assert_allclose(
        bayer.demosaic_bilinear(raw, pattern), _demosaic_by_convolution(raw, pattern), rtol=1e-12
    )


def test_demosaic_reproduces_linear_ramps_inside():
    yy, xx = np.mgrid[0:12, 0:14].astype(np.float64)
    rgb = np.stack([2 * xx + yy, 3 * yy - xx + 50, xx + 0.5 * yy], axis=-1)
    out = bayer.demosaic_bilinear(bayer.mosaic(rgb), "RGGB")
    np.testing.assert_allclose(out[1:-1, 1:-1], rgb[1:-1, 1:-1], atol=1e-9)


def test_bayer_capture_equals_mosaic_then_mono_capture():
    photons = np.random.default_rng(2).uniform(0, 2e4, (20, 30, 3))
    colour = SensorModel.from_preset("grasshopper-icx285")
    mono = colour.replace(bayer=None)
    a = colour.capture(photons, exposure_ms=45.0, seed=4)
    b = mono.capture(bayer.mosaic(photons, "RGGB"), exposure_ms=45.0, seed=4)
    assert np.array_equal(a, b)


# -------------------------------------------------------------------------- light levels
def test_photons_scale_with_light_level_exposure_and_open_area():
    ref = aperture_area_mm2(7.0)
    base = photons_per_unit(1000.0, 10.0, ref / 4, ref)
    assert base == pytest.approx(2500.0)
    assert photons_per_unit(2000.0, 10.0, ref / 4, ref) == pytest.approx(2 * base)
    assert photons_per_unit(1000.0, 5.0, ref / 4, ref) == pytest.approx(base / 2)
    assert photons_per_unit(1000.0, 10.0, ref / 2, ref) == pytest.approx(2 * base)
    img = np.array([[0.0, 0.5], [1.0, 2.0]])
    np.testing.assert_allclose(photons_from_render(img, 1000.0, 10.0, ref / 4, ref), img * base)


def test_simulate_capture_is_unbiased_and_shaped_for_the_cli():
    model = SensorModel.from_preset("grasshopper-icx285")
    img = np.full((64, 80, 3), 0.5)
    ref = aperture_area_mm2(7.0)
    cap = simulate_capture(
        img,
        model,
        exposure_ms=45.0,
        seed=1,
        light_level=DEFAULT_LIGHT_LEVEL,
        open_area_mm2=ref * (2.8 / 9.85) ** 2,  # F9.85 opening of an F2.8 lens
        reference_area_mm2=ref,
    )
    assert cap.raw_dn.shape == (64, 80) and cap.raw_dn.dtype == np.uint16
    assert cap.linear.shape == (64, 80, 3) and cap.linear.dtype == np.float32
    assert cap.photons_per_unit == pytest.approx(7000.0 * 45.0 * (2.8 / 9.85) ** 2)
    assert cap.linear.mean() == pytest.approx(0.5, rel=0.005)
    assert 0.5 * cap.photons_per_unit * model.qe < 0.8 * model.full_well_e  # not saturated


def test_linear_layer_subtracts_black_offset_and_dark_signal():
    m = ideal(dark_current_e_per_s=1e4, black_offset_dn=500.0, K=1.5, read_noise_e=2.0)
    dark = m.capture(np.zeros((200, 200)), exposure_ms=10.0, seed=3)  # 100 e- of dark signal
    assert m.linear_from_dn(dark, 1000.0, exposure_ms=10.0).mean() == pytest.approx(0, abs=1e-3)
    grey = m.capture(np.full((200, 200), 400.0), exposure_ms=10.0, seed=4)
    assert m.linear_from_dn(grey, 1000.0, exposure_ms=10.0).mean() == pytest.approx(0.4, rel=2e-3)


def test_simulate_capture_paper_convention():
    model = SensorModel.from_preset("paper")
    img = np.random.default_rng(3).uniform(0, 1, (200, 300))
    cap = simulate_capture(img, model, exposure_ms=45.0, seed=2)
    assert cap.raw_dn.shape == img.shape
    assert (cap.linear - img).std() == pytest.approx(0.01, rel=0.03)


# ---------------------------------------------------------------------- property tests
@settings(max_examples=60, deadline=None)
@given(
    qe=st.floats(0.01, 1.0),
    K=st.floats(0.01, 20.0),
    fw=st.floats(10.0, 1e6),
    bits=st.integers(1, 32),
    read=st.floats(0.0, 100.0),
    dark=st.floats(0.0, 1e4),
    prnu=st.floats(0.0, 0.5),
    photons=st.lists(st.floats(0.0, 1e12), min_size=1, max_size=40),
    seed=st.integers(0, 2**32),
)
def test_any_valid_model_gives_integer_dn_in_range(
    qe, K, fw, bits, read, dark, prnu, photons, seed
):
    m = SensorModel(
        qe=qe,
        K=K,
        full_well_e=fw,
        bit_depth=bits,
        read_noise_e=read,
        dark_current_e_per_s=dark,
        prnu=prnu,
        black_offset_dn=float(2 ** (bits - 1) // 2),
    )
    p = np.array(photons)
    dn = m.capture(p, exposure_ms=10.0, seed=seed)
    assert dn.shape == p.shape and dn.dtype.kind == "u"
    assert dn.min() >= 0 and dn.max() <= m.max_dn
    assert np.array_equal(dn, m.capture(p, exposure_ms=10.0, seed=seed))


@settings(max_examples=60, deadline=None)
@given(
    K=st.floats(0.01, 10.0),
    photons=st.lists(st.floats(0.0, 1e7), min_size=2, max_size=50),
)
def test_noise_free_response_is_monotone(K, photons):
    m = ideal(shot_noise=False, K=K, full_well_e=5e6, bit_depth=20)
    p = np.sort(np.array(photons))
    assert np.all(np.diff(m.capture(p).astype(np.int64)) >= 0)


@settings(max_examples=40, deadline=None)
@given(qe=st.one_of(st.floats(max_value=0.0), st.floats(min_value=1.0, exclude_min=True)))
def test_qe_outside_unit_interval_is_rejected(qe):
    with pytest.raises(ParameterError, match=r"qe must"):
        SensorModel(qe=qe)


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"qe": 0.0}, r"qe must be in \(0, 1\]"),
        ({"qe": 1.01}, r"qe must be in \(0, 1\]"),
        ({"qe": float("nan")}, r"qe must be a finite number"),
        ({"qe": "0.5"}, r"qe must be a number"),
        ({"qe": None}, r"qe must be a number"),
        ({"K": 0.0}, r"K must be > 0 DN/e-"),
        ({"K": -1.0}, r"K must be > 0"),
        ({"full_well_e": 0.0}, r"full_well_e must be > 0"),
        ({"full_well_e": -5.0}, r"full_well_e must be > 0"),
        ({"bit_depth": 0}, r"bit_depth must be an integer 1\.\.32"),
        ({"bit_depth": 33}, r"bit_depth must be an integer 1\.\.32"),
        ({"bit_depth": 12.5}, r"bit_depth must be an integer 1\.\.32"),
        ({"bit_depth": True}, r"bit_depth must be an integer 1\.\.32"),
        ({"read_noise_e": -1.0}, r"read_noise_e must be >= 0 e-"),
        ({"read_noise_e": float("inf")}, r"read_noise_e must be a finite number"),
        ({"dark_current_e_per_s": -1.0}, r"dark_current_e_per_s must be >= 0 e-/s"),
        ({"prnu": -0.1}, r"prnu must be >= 0"),
        ({"prnu": 1.5}, r"prnu must be in \[0, 1\]"),
        ({"dsnu_e": -1.0}, r"dsnu_e must be >= 0 e-"),
        ({"black_offset_dn": -1.0}, r"black_offset_dn must be >= 0 DN"),
        ({"black_offset_dn": 4096.0, "bit_depth": 12}, r"black_offset_dn must be in \[0, 4095\]"),
        ({"bayer": "RGBG"}, r"bayer must be one of RGGB, BGGR, GRBG, GBRG"),
        ({"seed": -1}, r"seed must be an integer >= 0"),
        ({"shot_noise": "yes"}, r"shot_noise must be true or false"),
    ],
)
def test_bad_parameters_raise(kw, match):
    with pytest.raises(ParameterError, match=match):
        SensorModel(**kw)


@pytest.mark.parametrize(
    ("photons", "match"),
    [
        (np.array([1.0, -0.5]), r"photons must be >= 0 photons"),
        (np.array([1.0, np.nan]), r"photons must be finite"),
        (np.array([np.inf]), r"photons must be finite"),
        (np.array([-3]), r"photons must be >= 0 photons"),
        (np.array([1 + 1j]), r"photons must be a real numeric array"),
        (np.array(["a"]), r"photons must be a real numeric array"),
    ],
)
def test_bad_photons_raise(photons, match):
    with pytest.raises(ParameterError, match=match):
        ideal().capture(photons, seed=0)


def test_bad_photons_raise_in_any_block():
    photons = np.ones(3 * (1 << 16))
    photons[-1] = np.nan
    with pytest.raises(ParameterError, match="photons must be finite"):
        ideal().capture(photons, seed=0, workers=2)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"exposure_ms": -1.0}, r"exposure_ms must be >= 0 ms"),
        ({"exposure_ms": float("nan")}, r"exposure_ms must be a finite number"),
        ({"seed": -1}, r"seed must be an integer >= 0"),
        ({"seed": 1.5}, r"seed must be an integer >= 0"),
        ({"workers": 0}, r"workers must be an integer >= 1"),
    ],
)
def test_bad_capture_arguments_raise(kw, match):
    with pytest.raises(ParameterError, match=match):
        ideal().capture(np.ones(4), **{"seed": 0, **kw})


def test_bayer_capture_needs_an_image_shape():
    m = SensorModel.from_preset("grasshopper-icx285")
    with pytest.raises(ParameterError, match=r"\(H, W, 3\) or an \(H, W\) mosaic"):
        m.capture(np.ones((4, 4, 4)), exposure_ms=1.0, seed=0)
    with pytest.raises(ParameterError, match=r"H, W >= 2"):
        bayer.demosaic_bilinear(np.ones((1, 5)))
    with pytest.raises(ParameterError, match=r"\(H, W\) mosaic"):
        bayer.demosaic_bilinear(np.ones((4, 4, 3)))


def test_unknown_preset_and_parameters_raise():
    with pytest.raises(ParameterError, match=r"unknown sensor preset 'nikon'.*grasshopper"):
        SensorModel.from_preset("nikon")
    with pytest.raises(ParameterError, match=r"unknown sensor parameter\(s\) gain"):
        SensorModel.from_preset("paper", gain=2.0)
    with pytest.raises(ParameterError, match=r"sigma must be >= 0"):
        SensorModel.from_preset("paper", sigma=-0.01)
    with pytest.raises(ParameterError, match=r"sigma or read_noise_e, not both"):
        SensorModel.from_preset("paper", sigma=0.01, read_noise_e=3.0)
    with pytest.raises(ParameterError, match=r"preset 'paper': qe must"):
        SensorModel.from_preset("paper", qe=2.0)


@pytest.mark.parametrize(
    ("name", "text", "match"),
    [
        ("bad.json", '{"qe": 0.5,', r"not valid JSON"),
        ("bad.toml", "qe = = 0.5", r"not valid TOML"),
        ("list.json", "[1, 2]", r"one table/object"),
        ("key.json", '{"gain": 2}', r"unknown key\(s\) gain"),
        ("type.json", '{"qe": "high"}', r"qe must be a number"),
        ("range.toml", "qe = 2.0", r"range\.toml: qe must be in \(0, 1\]"),
        ("bits.json", '{"bit_depth": 40}', r"bit_depth must be an integer 1\.\.32"),
        ("base.json", '{"base": "nikon"}', r"base must be one of"),
        ("both.json", '{"sigma": 0.1, "read_noise_e": 2}', r"sigma or read_noise_e"),
        ("cam.yaml", "qe: 0.5", r"\.json or \.toml"),
    ],
)
def test_malformed_preset_files_raise(tmp_path, name, text, match):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ParameterError, match=match):
        SensorModel.from_file(path)


def test_missing_preset_file_raises(tmp_path):
    with pytest.raises(ParameterError, match=r"preset file .*nope.json' does not exist"):
        SensorModel.from_preset(str(tmp_path / "nope.json"))


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.array([-1.0]), 1.0, 1.0, 1.0, 1.0), r"linear_image must be >= 0"),
        ((np.array([np.nan]), 1.0, 1.0, 1.0, 1.0), r"linear_image must be finite"),
        (
            (np.ones(2), 0.0, 1.0, 1.0, 1.0),
            r"light_level must be in \[1e-06, 1e\+09\] photons/px/ms",
        ),
        ((np.ones(2), 1.0, 0.0, 1.0, 1.0), r"exposure_ms must be > 0 ms"),
        ((np.ones(2), 1.0, 1.0, -1.0, 1.0), r"open_area_mm2 must be > 0"),
        ((np.ones(2), 1.0, 1.0, 1.0, 0.0), r"reference_area_mm2 must be > 0"),
    ],
)
def test_bad_light_level_arguments_raise(args, match):
    with pytest.raises(ParameterError, match=match):
        photons_from_render(*args)


def test_simulate_capture_argument_combinations():
    m = SensorModel.from_preset("paper")
    with pytest.raises(ParameterError, match=r"need a light_level"):
        simulate_capture(np.ones((2, 2)), m, exposure_ms=1.0, seed=0, open_area_mm2=1.0)
    with pytest.raises(ParameterError, match=r"needs open_area_mm2 and reference_area_mm2"):
        simulate_capture(np.ones((2, 2)), m, exposure_ms=1.0, seed=0, light_level=100.0)


def test_presets_table_is_not_mutated_by_overrides():
    before = json.dumps(PRESETS, sort_keys=True)
    SensorModel.from_preset("paper", sigma=0.5)
    SensorModel.from_preset("grasshopper-icx285", K=0.1, bayer=None)
    assert json.dumps(PRESETS, sort_keys=True) == before
