"""Captures: every scene in every mode, exposure integration against closed forms, resuming,
determinism, refusals and errors."""

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.camera import capture_design
from pacam_render.exposure.direct import CaptureInterrupted, render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.exposure.steps import plan_steps
from pacam_render.model.modes import MODES
from pacam_render.scenes import psf_scene

TINY = {"width": 48, "height": 36, "spp": 4}


@pytest.mark.parametrize("scene", ["train", "soccer", "walker"])
@pytest.mark.parametrize("mode", MODES)
def test_every_scene_every_mode(scene, mode):
    cap = render_capture(CaptureSpec.geometric(scene=scene, mode=mode, **TINY), progress=False)
    img = cap.image
    assert img.shape == (36, 48, 3) and np.all(np.isfinite(img)) and img.min() >= 0
    assert img.mean() > 0
    norm = img.mean() / cap.meta["light_factor"]  # every mode sees the same scene brightness
    assert 0.02 < norm < 2.0


def test_modes_collect_light_in_proportion():
    """Normalised by the light factor, normal, coded and short agree with the reference."""
    means = {}
    for mode in ("reference", "normal", "coded", "short"):
        cap = render_capture(
            CaptureSpec.geometric(mode=mode, width=64, height=48, spp=16), progress=False
        )
        means[mode] = cap.image.mean() / cap.meta["light_factor"]
    for mode in ("normal", "coded", "short"):
        assert means[mode] == pytest.approx(means["reference"], rel=0.03)
    # short: F2.8 for 0.679 ms vs F9.85 for 45 ms: (9.85/2.8)^2 x 0.679/45 = 0.187 of the light
    short = capture_design(CaptureSpec.geometric())
    assert short.R_max_mm**2 * 0.679 / (short.R_mm**2 * 45) == pytest.approx(0.1868, abs=1e-3)


def streak_length_px(row: np.ndarray) -> float:
    """Length of a box from its variance: L^2/12 plus the pixel's own 1/12."""
    x = np.arange(row.size)
    w = row / row.sum()
    mu = (w * x).sum()
    var = (w * (x - mu) ** 2).sum()
    return float(np.sqrt(12 * (var - 1 / 12)))


def test_moving_emitter_streak_matches_velocity_times_exposure():
    spec = CaptureSpec.geometric(scene="psf", mode="normal", width=96, height=16, spp=1024)
    cam = capture_design(spec)
    v = 1.2  # px/ms in this film's pixels
    desc = psf_scene(500.0, v, camera=cam.with_(focus_distance_mm=500.0), radius_mm=0.05)
    cap = render_capture(spec, progress=False, description=desc)
    row = cap.image[..., 0].sum(axis=0)
    assert streak_length_px(row) == pytest.approx(v * 45.0, abs=0.5)
    assert cap.meta["n_steps"] >= v * 45 / 0.5  # no step moves more than 0.5 px


def test_static_scene_is_one_pass_without_geometry_updates():
    spec = CaptureSpec.geometric(scene="psf", mode="coded", width=64, height=32, spp=16)
    desc = psf_scene(500.0, 0.0, camera=capture_design(spec))
    cap = render_capture(spec, progress=False, description=desc)
    assert cap.meta["n_steps"] == 1 and cap.meta["n_geometry_updates"] == 0


def test_plan_steps_respects_step_size_and_spp_budget():
    spec = CaptureSpec.geometric(spp=64, max_step_px=0.5)
    edges = np.linspace(0, 45, 17)
    steps = plan_steps(edges, np.ones(16, bool), 1.4, spec)
    assert all((s.t1 - s.t0) * 1.4 <= 0.5 + 1e-9 for s in steps)
    assert sum(s.spp for s in steps) == max(64, len(steps))
    assert [s.pattern for s in steps] == sorted(s.pattern for s in steps)
    flutter = plan_steps(np.linspace(0, 45, 5), np.array([1, 0, 0, 1], bool), 0.0, spec)
    assert [s.pattern for s in flutter] == [0, 3]  # closed chops are never rendered


def test_same_seed_is_bit_identical_and_resume_matches(tmp_path):
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=64, height=48, spp=32, seed=7)
    full = render_capture(spec, progress=False).image
    again = render_capture(spec, progress=False).image
    assert np.array_equal(full, again)
    other = render_capture(
        CaptureSpec.geometric(**{**spec.__dict__, "seed": 8}), progress=False
    ).image
    assert not np.array_equal(full, other)
    part = tmp_path / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=5)
    assert (part / "state.json").is_file()
    resumed = render_capture(spec, partial_dir=part, progress=False)
    assert resumed.meta["resumed_from_step"] == 5
    assert np.array_equal(resumed.image, full)
    assert not part.exists()  # cleaned up once finished


def test_cli_render_writes_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "c"
    args = ["render", "train", "--mode", "coded", "--width", "40", "--height", "30", "--spp", "4"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    meta = json.loads((out / "capture.json").read_text())
    assert meta["spec"]["seed"] == 0 and "versions" in meta and meta["camera"]["width_px"] == 40
    assert (out / "capture.png").stat().st_size > 0
    before = (out / "capture.exr").read_bytes()
    assert main([*args, "--out", str(out), "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "capture.exr").read_bytes() == before
    assert main([*args, "--out", str(out), "--quiet", "--force"]) == 0
    assert (out / "capture.exr").read_bytes() == before  # same seed: the same file


def test_cli_render_with_sensor_layers(tmp_path):
    from pacam_render.io.exr import read_exr

    out = tmp_path / "s"
    argv = [
        "render",
        "train",
        "--mode",
        "short",
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--sensor",
        "grasshopper-icx285",
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(argv) == 0
    layers = read_exr(out / "capture.exr")
    assert set(layers) == {
        "capture", "raw", "noisy", "sharp", "depth", "object_id", "velocity",
        "relative_illumination",  # pacam render's default cos4 records its map
    }  # fmt: skip
    assert layers["raw"].shape == (30, 40)  # the Bayer mosaic
    assert np.all(layers["raw"] == np.round(layers["raw"]))
    noise = layers["noisy"] - layers["capture"]
    assert (
        np.std(noise) > 0 and abs(np.mean(noise)) < 5 * np.std(noise) / np.sqrt(noise.size) + 1e-4
    )


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"scene": "nonsense"}, "unknown scene"),
        ({"mode": "sideways"}, "unknown mode"),
        ({"width": 0}, "width"),
        ({"spp": 0}, "spp"),
        ({"max_step_px": -1.0}, "max_step_px"),
    ],
)
def test_bad_input_errors(kw, match):
    with pytest.raises(ParameterError, match=match):
        render_capture(CaptureSpec.geometric(**{**TINY, **kw}), progress=False)


def test_unparsable_scene_file(tmp_path, capsys):
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='nonexistent_shape'/></scene")
    assert main(["render", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "bad.xml" in err


def test_cli_checks_options_before_rendering(tmp_path, capsys):
    out = tmp_path / "never"
    argv = ["render", "train", "--sensor", "paper", "--light-level", "-5", "--out", str(out)]
    assert main(argv) == 2
    assert "--light-level must be in [1e-06, 1e+09]" in capsys.readouterr().err
    assert not out.exists()  # nothing rendered, nothing written
    assert main(["reproduce", "fig9", "--quick", "--seed", "-1", "--out", str(out)]) == 2
    assert "--seed must be" in capsys.readouterr().err and not out.exists()
