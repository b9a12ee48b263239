"""Relative illumination through a capture: the spec and its key, the sensor parameters, the
recorded map and block in capture.json, flat-fielding on reading and in ``pacam deconvolve``,
and the CLI flag.

References: the map of :func:`~pacam_render.model.illumination.relative_illumination_map`
(tested against cos^4 and the plugin in tests/render/test_relative_illumination.py), the same
capture rendered with ``off`` (same seed: same samples), and the pinhole ``sharp`` layer.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict

import numpy as np
import pytest

from pacam_render.capture.files import read_capture
from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.camera import illumination_params
from pacam_render.exposure.direct import render_capture, write_capture
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model.illumination import relative_illumination_map
from pacam_render.restore.flat_field import FlatFieldNoise, flat_field_sigma
from pacam_render.restore.noise import NoiseModel

TINY = {"scene": "train", "mode": "normal", "width": 48, "height": 36, "spp": 8, "seed": 3,
        "max_step_px": 4.0}  # fmt: skip
"""One time step a pass (the train moves 1.7 px here), so the passes keep ldsampler: these
tests weigh the relative illumination on the same stratified samples, not the time steps."""


def test_spec_default_is_off_and_keeps_the_key():
    spec = CaptureSpec.geometric(**TINY)
    assert spec.relative_illumination == "off"
    fields = asdict(spec)
    del fields["grey"], fields["relative_illumination"]  # the key as it was before the field
    del fields["diffraction"]  # a post-render choice, never in the key
    del fields["lcos_contrast"], fields["lcos_fill_factor"], fields["lcos_switching_ms"]
    old = hashlib.sha256(json.dumps(fields, sort_keys=True).encode()).hexdigest()[:16]
    assert spec.key() == old
    cos4 = CaptureSpec(**TINY, relative_illumination="COS4")
    assert cos4.relative_illumination == "cos4" and cos4.key() != old


def test_spec_checks_the_setting_and_hashes_a_curve(tmp_path):
    with pytest.raises(ParameterError, match="relative_illumination must be off, cos4"):
        CaptureSpec(**TINY, relative_illumination="cos2")
    curve = tmp_path / "lens.csv"
    with pytest.raises(ParameterError, match="lens.csv: no such file"):
        CaptureSpec(**TINY, relative_illumination=str(curve))
    curve.write_text("field_deg,relative_illumination\n0,1\n40,0.5\n")
    a = CaptureSpec(**TINY, relative_illumination=str(curve)).key()
    curve.write_text("field_deg,relative_illumination\n0,1\n40,0.6\n")
    assert CaptureSpec(**TINY, relative_illumination=str(curve)).key() != a  # edited in place


def test_sensor_parameters(tmp_path):
    pitch = 0.00645 * 1280 / 48
    assert illumination_params(CaptureSpec.geometric(**TINY), pitch) == {}
    assert illumination_params(CaptureSpec(**TINY, relative_illumination="cos4"), pitch) == {
        "relative_illumination": "cos4"
    }
    ref = CaptureSpec(**{**TINY, "mode": "reference"}, relative_illumination="cos4")
    assert illumination_params(ref, pitch) == {}  # the pinhole truth stays radiance
    curve = tmp_path / "c.json"
    curve.write_text(json.dumps({"height_mm": [0, 5], "relative_illumination": [1, 0.5]}))
    spec = CaptureSpec(**TINY, relative_illumination=str(curve))
    # 48 px across the 1280 px, 6.45 um sensor: pixels of 172 um
    plan = plan_capture(spec)
    assert plan.pitch_mm == pytest.approx(pitch)
    assert plan.optics_params["pixel_pitch"] == plan.pitch_mm


@pytest.fixture(scope="module")
def pair():
    off = render_capture(CaptureSpec.geometric(**TINY), progress=False)
    cos4 = render_capture(CaptureSpec(**TINY, relative_illumination="cos4"), progress=False)
    return off, cos4


@pytest.mark.render
def test_capture_is_the_radiance_capture_times_the_map(pair):
    off, cos4 = pair
    m = relative_illumination_map("cos4", 48, 36, 46.0)
    assert np.array_equal(cos4.extra_layers["relative_illumination"], m.astype(np.float32))
    assert "relative_illumination" not in off.extra_layers
    lit = off.image.sum(axis=-1) > 1e-3 * off.image.mean()  # a few pixels see nothing
    assert lit.mean() > 0.9
    ratio = cos4.image.sum(axis=-1)[lit] / off.image.sum(axis=-1)[lit]
    # same samples; only the radiance's variation inside a pixel weighs the factor unevenly
    assert np.abs(ratio / m[lit] - 1).max() < 0.02 and np.abs(ratio / m[lit] - 1).mean() < 2e-3
    assert np.array_equal(cos4.extra_layers["sharp"], off.extra_layers["sharp"])  # the pinhole
    rec = cos4.meta
    assert rec["sensor_params"]["relative_illumination"] == "cos4"
    assert rec["spec"]["relative_illumination"] == "cos4"
    block = rec["relative_illumination"]
    assert block["setting"] == "cos4" and block["min"] == pytest.approx(m.min(), rel=1e-6)
    assert block["thin_lens_exact_over_cos4_at_corner"] == pytest.approx(1.0019, abs=2e-4)
    assert "relative_illumination" not in off.meta  # off: the record is as it was
    assert "relative_illumination" not in off.meta["sensor_params"]


@pytest.mark.render
def test_reading_flat_fields(pair, tmp_path):
    off, cos4 = pair
    write_capture(cos4, tmp_path / "cos4", force=False)
    write_capture(off, tmp_path / "off", force=False)
    a = read_capture(tmp_path / "cos4")
    b = read_capture(tmp_path / "off")
    assert "relative_illumination" in a.units and a.units["relative_illumination"]
    # flat-fielded: the radiance capture again, up to the in-pixel weighting
    rel = np.abs(a.layers["capture"] - b.layers["capture"]).mean() / b.layers["capture"].mean()
    assert rel < 2e-3
    assert json.loads((tmp_path / "cos4" / "capture.json").read_text())["relative_illumination"]


@pytest.mark.render
def test_reference_mode_ignores_it_with_a_note():
    spec = CaptureSpec(**{**TINY, "mode": "reference"}, relative_illumination="cos4")
    with pytest.warns(Warning, match="relative_illumination has no effect in reference mode"):
        cap = render_capture(spec, progress=False, truth=False)
    assert "relative_illumination" not in cap.extra_layers


@pytest.mark.render
def test_cli_render_and_deconvolve_flat_field(tmp_path, capsys):
    out = tmp_path / "cap"
    argv = ["render", "train", "--mode", "normal", "--width", "48", "--height", "36"]
    argv += ["--spp", "8", "--sensor", "grasshopper-icx285", "--quiet"]
    assert main([*argv, "--relative-illumination", "cos4", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "relative illumination cos4: 0.6" in printed and "relative_illumination" in printed
    assert main(["deconvolve", str(out / "capture.exr"), "--out", str(out / "d")]) == 0
    meta = json.loads((out / "d" / "deconvolved.json").read_text())
    assert meta["flat_fielded"] is True and np.isfinite(meta["psnr_db"])
    # off: nothing is flat-fielded
    plain = tmp_path / "plain"
    assert main([*argv, "--relative-illumination", "off", "--out", str(plain)]) == 0
    assert main(["deconvolve", str(plain / "capture.exr"), "--out", str(plain / "d")]) == 0
    assert json.loads((plain / "d" / "deconvolved.json").read_text())["flat_fielded"] is False


def test_cli_refuses_a_bad_curve_naming_the_flag_and_the_file(tmp_path, capsys):
    bad = tmp_path / "lens.csv"
    bad.write_text("height_px,relative_illumination\n0,1\n10,oops\n")
    out = tmp_path / "never"
    argv = ["render", "train", "--relative-illumination", str(bad), "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    # the file's contents in its own words (issue 47, medium 6): its column, not the flag
    assert "relative_illumination file" in err and "lens.csv line 3" in err
    assert "--relative-illumination" not in err
    assert "Traceback" not in err and not out.exists()
    assert main(["render", "train", "--relative-illumination", "cos", "--out", str(out)]) == 2
    assert "--relative-illumination must be off, cos4" in capsys.readouterr().err


def test_flat_field_noise_is_the_raw_noise_divided():
    raw = NoiseModel(shot=2e-3, floor=1e-5, prnu=0.01, saturation=1.5)
    g = np.array([[1.0, 0.5], [0.8, 0.25]])
    ff = FlatFieldNoise.of(raw, g)
    s = np.array([[0.3, 0.6], [0.1, 1.0]])  # flat-fielded signal: raw signal s g
    assert np.allclose(ff.variance(s), raw.variance(s * g) / g**2)
    assert np.allclose(ff.scaled(3.0).variance(s), raw.scaled(3.0).variance(s * g) / g**2)
    assert np.array_equal(ff.saturated(np.array([[1.6, 3.1], [1.0, 6.0]])), [[1, 1], [0, 1]])
    planes = np.stack([s, s])  # (C, H, W), as the solvers pass them
    assert ff.variance(planes).shape == (2, 2, 2)
    assert flat_field_sigma(0.01, np.full((3, 3), 0.5)) == pytest.approx(0.02)
