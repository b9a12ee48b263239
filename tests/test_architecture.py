"""The package's shape: light import, plugin registration across variants, one table of modes,
and the typed capture record."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.capture import MODES as CAPTURE_MODES
from pacam_render.exposure.capture import mode_camera
from pacam_render.exposure.psf_render import RENDER_MODES, mode_setup
from pacam_render.exposure.record import CaptureRecord, SensorRecord
from pacam_render.model import paper
from pacam_render.model.camera import prototype
from pacam_render.model.modes import MODES, MODES_WITH_PSF, capture_camera, mode, t0_offset_px
from pacam_render.psf.analytic import design_psf


def _python(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_import_is_light_and_the_plugin_registers_on_first_use():
    code = (
        "import sys, pacam_render as pr\n"
        "print(sorted(m for m in ('mitsuba', 'drjit') if m in sys.modules))\n"
        "pr.select_variant()\n"
        "import mitsuba as mi\n"
        "s = mi.load_dict(pr.sensor_dict(lens_radius=5.0, fov=40))\n"
        "print(type(s).__name__)\n"
    )
    lines = _python(code).splitlines()
    assert lines[0] == "[]"
    assert lines[-1] == "ProgrammableApertureCamera"


def test_both_plugins_follow_variant_switches():
    """After a switch to scalar_rgb and back, both sensors load again (module re-import)."""
    code = (
        "from pacam_render import render\n"
        "import mitsuba as mi\n"
        "v = render.select_variant()\n"
        "for variant in ('scalar_rgb', v):\n"
        "    mi.set_variant(variant)\n"
        "    for plugin in (render.PLUGIN_NAME, render.PSF_PLUGIN_NAME):\n"
        "        d = render.sensor_dict(lens_radius=5.0, fov=40)\n"
        "        d['type'] = plugin\n"
        "        s = mi.load_dict(d)\n"
        "        print(variant, type(s).__name__, isinstance(s, mi.Sensor))\n"
    )
    lines = _python(code).splitlines()
    assert [ln.split()[1:] for ln in lines] == [
        ["ProgrammableApertureCamera", "True"],
        ["PSFCamera", "True"],
    ] * 2
    assert lines[0].startswith("scalar_rgb")


def test_every_mode_is_in_the_one_table():
    assert set(CAPTURE_MODES) == set(MODES)
    assert set(RENDER_MODES) == set(MODES_WITH_PSF) == {m for m in MODES if MODES[m].psf}
    assert "reference" in MODES and "reference" not in MODES_WITH_PSF
    with pytest.raises(ParameterError, match="valid: normal, coded"):
        mode("blurry")
    with pytest.raises(ParameterError, match="valid"):
        design_psf(prototype(), "reference")


@pytest.mark.parametrize("name", MODES_WITH_PSF)
def test_capture_and_psf_render_configure_the_same_sensor(name):
    """The capture of a mode and the PSF rendering of its camera show the same schedule."""
    design = prototype()
    cam, params = mode_camera(design, name)
    setup = mode_setup(cam, name)
    assert setup.sensor == params
    assert setup.exposure_ms == cam.exposure_ms
    assert setup.origin_px == pytest.approx(t0_offset_px(cam, name))


def test_mode_policies_against_the_paper():
    design = prototype()
    short = capture_camera(design, "short")
    assert short.exposure_ms == paper.SHORT_EXPOSURE_MS
    assert short.F_number == pytest.approx(paper.F_MIN)  # the whole lens open
    assert short.r_px == pytest.approx(0.0, abs=1e-9)  # focused on the object
    normal = capture_camera(design, "normal")
    assert normal.R_mm == design.R_mm and normal.r_px == pytest.approx(0.0, abs=1e-9)
    assert capture_camera(design, "coded") == design == capture_camera(design, "levin")
    assert mode_camera(design, "levin")[1]["focus_distance"] == design.object_depth_mm
    # the t = 0 image offset is -beta (R_max - R) = -a_i T^2 / 4 (Eqs. 10, 17)
    beta_travel = -design.beta_px_per_mm * (design.R_max_mm - design.R_mm)
    assert t0_offset_px(design, "coded") == pytest.approx(beta_travel, rel=1e-9)
    assert t0_offset_px(design, "normal") == 0.0
    # the short kernel is a box of |s| x 0.679 ms
    k = design_psf(short, "short", 10.0, size=(1, 15))
    assert 1.0 / k.max() == pytest.approx(10.0 * paper.SHORT_EXPOSURE_MS)  # 1/L per full px


def _record(**over) -> CaptureRecord:
    base = dict(
        spec={"mode": "coded"},
        mode="coded",
        camera=prototype().inputs(),
        optics={},
        coded_design={},
        sensor_params={},
        exposure_ms=45.0,
        reference_exposure_ms=45.0,
        light_factor=0.25,
        render_seconds=1.0,
        variant="llvm_ad_rgb",
        versions={},
    )
    return CaptureRecord(**{**base, **over})


def test_record_round_trips_through_json():
    rec = _record(
        sensor=SensorRecord("paper", {"qe": 1.0}, None, 1.5, 3, noise_sigma_white_units=0.02),
        noise_sigma=0.005,
        resumed_from_step=4,
    )
    d = json.loads(json.dumps(rec.to_json()))
    assert d["sensor"]["noise_sigma_white_units"] == 0.02 and d["noise_sigma"] == 0.005
    assert "fastest_image_speed_px_per_ms" not in d  # unset optional fields are left out
    back = CaptureRecord.from_json(d)
    assert back == rec
    assert back.known_noise_sigma == 0.005


def test_record_reads_the_older_demo_sensor_block():
    d = _record().to_json()
    d["sensor"] = {"preset": "grasshopper-icx285", "light_level": 300.0, "seed": 0,
                   "photons_per_unit": 2.0, "noise_sigma_white_units": 0.04}  # fmt: skip
    d["future_key"] = [1, 2]
    rec = CaptureRecord.from_json(d)
    assert rec.sensor.light_level_photons_per_px_per_ms == 300.0
    assert rec.known_noise_sigma == pytest.approx(0.04 * 0.25)  # white units x light factor
    assert rec.to_json()["future_key"] == [1, 2]  # unknown keys are kept


def test_record_without_camera_is_a_clear_error():
    with pytest.raises(ParameterError, match="lacks 'camera'"):
        CaptureRecord.from_json({"mode": "coded"}, where="x.json")
    with pytest.raises(ParameterError, match="JSON object"):
        CaptureRecord.from_json([1, 2], where="x.json")
