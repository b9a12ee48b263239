"""The physics error budget and the diffraction settings of a capture (issue 36).

References: Rayleigh's closed form of the Airy pattern's encircled energy and scipy's Bessel
functions (the ray table), brute-force Monte Carlo noise through a kernel (the effect's noise
correction), the cos^4 law written out, the diffraction scale of :mod:`pacam_render.wave.scale`
(an implementation apart from the plugin's), and hand-built records.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import j1

from pacam_render.capture import optics_error as oe
from pacam_render.errors import ParameterError
from pacam_render.exposure.optics.diffraction import check_diffraction, decide, effect_rms
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model.camera import prototype
from pacam_render.model.modes import capture_camera
from pacam_render.render.ray_diffraction import (
    MAX_LOST,
    RayDiffractionSpec,
    encircled_energy,
    parse_wavelengths,
    radial_table,
)
from pacam_render.study.point import optics_columns
from pacam_render.study.results import row_digest, row_is_intact
from pacam_render.wave.image import diffract_image
from pacam_render.wave.scale import scale_for


# --- the rays' Airy table -------------------------------------------------------------------
def test_radial_table_leaves_out_what_it_says_and_follows_the_airy_density():
    v_max, pdf, lost, l1 = radial_table()
    assert lost <= MAX_LOST and lost == pytest.approx(1 - encircled_energy(v_max), abs=1e-12)
    v = np.linspace(0, v_max, pdf.size)
    inside = np.trapezoid(pdf.astype(float), v) / 2.0  # the density integrates to 2 over v
    assert inside == pytest.approx(1 - lost, abs=2e-4)
    mid = 0.5 * (v[1000] + v[1001])  # between nodes: the linear table against scipy's J1
    assert np.interp(mid, v, pdf) == pytest.approx(4 * j1(mid) ** 2 / mid, abs=1e-5)
    assert l1 < 1e-3


def test_encircled_energy_is_the_integral_of_the_density():
    v = np.linspace(1e-9, 30, 300001)
    density = 4 * j1(v) ** 2 / v
    steps = np.diff(v) * 0.5 * (density[1:] + density[:-1])
    cumulative = np.concatenate([[0.0], np.cumsum(steps)]) / 2
    assert np.allclose(cumulative[::30000], encircled_energy(v[::30000]), atol=1e-6)
    assert encircled_energy(3.8317) == pytest.approx(0.838, abs=1e-3)  # first dark ring: 83.8 %


def test_ray_scale_matches_the_wave_librarys():
    cam = capture_camera(prototype(), "normal")
    rays = RayDiffractionSpec("611, 549, 464", 2 * cam.F_min * cam.R_max_mm, cam.pixel_pitch_mm)
    for got, wl in zip(rays.lambda_n_px(cam.R_mm), (611, 549, 464)):
        assert got == pytest.approx(scale_for(cam, wl).lambda_n_px(cam.R_mm), rel=1e-12)
    assert 1.22 * rays.lambda_n_px(cam.R_mm)[1] == pytest.approx(1.02, abs=0.01)  # F9.85


@pytest.mark.parametrize("bad", ["", "green", "200", "611, 2000", [1, 2]])
def test_wavelengths_are_checked(bad):
    with pytest.raises(ParameterError, match="diffraction_wavelengths must be"):
        parse_wavelengths(bad)


def test_ray_spec_names_its_parameters():
    with pytest.raises(ParameterError, match="pupil_distance"):
        RayDiffractionSpec("549", 0.0, 0.00645)
    with pytest.raises(ParameterError, match="pixel_pitch"):
        RayDiffractionSpec("549", 39.0, -1.0)


# --- the setting and auto's measure -----------------------------------------------------------
def test_setting_is_checked_on_the_spec_and_enters_the_key_unless_off():
    """Diffraction in the rays changes the passes: a resume must never mix passes with and
    without it, so on and auto have keys of their own; off keeps the key of a spec that
    predates the field (the spec's default)."""
    with pytest.raises(ParameterError, match="diffraction must be one of auto, on, off"):
        CaptureSpec(diffraction="maybe")
    with pytest.raises(ParameterError, match="diffraction must be one of"):
        check_diffraction(True)
    keys = {d: CaptureSpec.geometric(diffraction=d).key() for d in ("off", "on", "auto")}
    assert len(set(keys.values())) == 3
    assert keys["off"] == CaptureSpec.geometric().key()


def test_decide():
    assert decide("on", 0.0, 1.0, "x") == (True, "on, as asked")
    assert decide("off", 9.0, 1.0, "x")[0] is False
    keep, text = decide("auto", 2e-3, 1e-3, "the noise target")
    assert keep and text.startswith("auto: included, its effect 0.002 >= the noise target")
    assert decide("auto", 5e-4, 1e-3, "t")[0] is False


def test_effect_rms_removes_the_monte_carlo_noise():
    """Pure noise of known variance through a kernel: the raw RMS change is the noise's, and
    the corrected effect is ~0 (brute force over many pixels); a real change survives."""
    rng = np.random.default_rng(3)
    k = np.zeros((5, 5))
    k[1:4, 1:4] = 1 / 9.0

    class D:
        kernel = k

    sigma = 0.01
    img = 0.5 + sigma * rng.standard_normal((256, 256))
    out = diffract_image(img, k)
    raw = float(np.sqrt(np.mean((out - img) ** 2)))
    var = np.full(img.shape, sigma**2)
    assert raw > 0.009
    assert effect_rms(img, out, var, [[D]]) < 0.1 * raw
    step = np.zeros((256, 256))
    step[:, 128:] = 1.0
    true = float(np.sqrt(np.mean((diffract_image(step, k) - step) ** 2)))
    noisy = step + sigma * rng.standard_normal(step.shape)
    got = effect_rms(noisy, diffract_image(noisy, k), var, [[D]])
    assert got == pytest.approx(true, rel=0.05)


# --- the budget -------------------------------------------------------------------------------
def _block(image, ri_record=None, cos4=None):
    effects = {
        "diffraction": oe.entry(False, "left out", 0.002),
        "relative_illumination": oe.relative_illumination_entry(image, cos4, ri_record),
        "lcos_leakage": oe.leakage_entry(image, 12.0),
        "lcos_grid": oe.grid_entry(image),
        "lcos_switching": oe.switching_entry(image, 16, 45.0),
        "bounces": oe.bounces_entry(image, "train", {"type": "path", "max_depth": 3}),
    }
    return {"diffraction": {}, "effects": effects}


def test_budget_sizes_follow_their_closed_forms():
    img = np.full((4, 6, 3), 0.1)
    cos4 = np.full((4, 6), 0.8)
    block = _block(img, cos4=cos4)
    oe.add_ratios(block, 0.001, "a sensor")
    e = block["effects"]
    assert e["relative_illumination"]["size_rms"] == pytest.approx(0.1 * 0.2)
    assert e["lcos_leakage"]["size_rms_per_inverse_contrast"] == pytest.approx(0.1 * 11)
    assert e["lcos_leakage"]["contrast_at_sensor_noise"] == pytest.approx(1100)
    assert e["lcos_grid"]["fill_factor_at_sensor_noise"] == pytest.approx(1 - 0.001 / 0.1)
    assert e["lcos_switching"]["switching_ms_at_sensor_noise"] == pytest.approx(
        0.001 / (15 / 45.0 * 0.1)
    )
    assert e["bounces"]["size_rms"] == pytest.approx(8e-4 * 0.1)
    assert e["relative_illumination"]["ratio_to_sensor"] == pytest.approx(20.0)
    assert block["largest_left_out"] == "relative_illumination"
    assert "relative illumination, RMS 0.02, 20x" in oe.summary_line(block)


def test_budget_edges():
    img = np.zeros((3, 3))
    block = _block(img, ri_record={"law": "cos^4", "thin_lens_exact_over_cos4_at_corner": 1.023})
    oe.add_ratios(block, None, "none")
    e = block["effects"]
    assert e["relative_illumination"]["included"]
    assert e["relative_illumination"]["approximation"] == pytest.approx(0.023)
    assert all(x["ratio_to_sensor"] is None for x in e.values())
    unknown = oe.bounces_entry(img, "my.xml", object())  # a scene file's Mitsuba integrator
    assert unknown["size_rms"] is None and "not measured" in unknown["estimate"]


def test_study_columns_and_old_rows_stay_intact():
    img = np.full((2, 2), 0.1)
    block = _block(img)
    oe.add_ratios(block, 0.01, "s")  # 0.001 would name a typical LCoS's switching (below)
    cols = optics_columns(block, 0.5)
    assert cols["diffraction"] == "out" and cols["diffraction_sigma"] == pytest.approx(0.004)
    assert cols["optics_left_out"] == "diffraction"
    old = {"point": "0", "scene": "train", "status": "ok", "psnr_db": "30.0"}
    old["row_digest"] = row_digest(old)
    assert row_is_intact(old)  # read back from a file written before the optics columns
    assert row_is_intact({**old, "diffraction": "", "optics_left_out": ""})
    new = {**old, **{k: str(v) for k, v in cols.items()}}
    new["row_digest"] = row_digest(new)
    assert row_is_intact(new) and not row_is_intact({**new, "diffraction": "in"})


def test_an_ideal_lcos_that_a_typical_device_is_not_is_named_the_largest_left_out():
    """Issue 46, item 5: 64 patterns in 20 ms switch 63 times; a typical (ferroelectric,
    0.1 ms) panel blends neighbours for 63 x 0.1 / 20 = 31.5 % of the exposure, far above a
    bright capture's noise: the budget names switching as the largest left out, and the line
    says which value to give. 16 patterns in 45 ms at a dim capture's noise stay quiet."""
    from pacam_render.capture import optics_error as oe

    image = np.full((8, 8), 0.1)

    def block(n, e_ms, sigma):
        effects = {
            "diffraction": oe.entry(False, "off", 1e-6),
            "lcos_leakage": oe.leakage_entry(image, 1.0 / 0.0625),
            "lcos_grid": oe.grid_entry(image),  # not weighed at a typical device: a veil
            "lcos_switching": oe.switching_entry(image, n, e_ms),
        }
        b = {"effects": effects}
        oe.add_ratios(b, sigma, "test")
        return b

    b = block(64, 20.0, 1e-3)
    sw = b["effects"]["lcos_switching"]
    assert sw["size_rms_at_typical"] == pytest.approx(63 * 0.1 / 20.0 * 0.1)
    assert sw["typical_matters"] and b["effects"]["lcos_leakage"]["typical_matters"]
    assert b["largest_left_out"] == "lcos_switching"
    line = oe.summary_line(b)
    assert "ideal LCoS's switching" in line and "`lcos_switching_ms`" in line
    proto = block(16, 45.0, 1e-4)  # the prototype blends 3 %: its loose bound is not weighed
    assert not proto["effects"]["lcos_switching"]["typical_matters"]
    quiet = block(16, 45.0, 0.5)
    assert not any(e.get("typical_matters") for e in quiet["effects"].values())
    assert quiet["largest_left_out"] == "diffraction"


@pytest.mark.render
def test_the_budget_names_a_stand_in_sensor(tmp_path, capsys):
    """Issue 47 (low): without `--sensor` the budget's ratios are over a stand-in sensor's
    noise (the design's preset or the ICX285 at the default light); the line said "the
    sensor's noise" as if the capture had one."""
    from pacam_render.cli import main

    args = ["render", "train", "--width", "32", "--height", "24", "--spp", "8",
            "--diffraction", "off", "--no-truth", "--quiet"]  # fmt: skip
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    line = next(s for s in out.splitlines() if s.startswith("optics left out"))
    assert "x the noise of a stand-in sensor (grasshopper-icx285 at " in line
    assert main([*args, "--sensor", "grasshopper-icx285", "--out", str(tmp_path / "b")]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("optics left"))
    assert "x the sensor's noise" in line and "stand-in" not in line
