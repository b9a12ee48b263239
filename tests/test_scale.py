"""The camera at its real scale (issue 13): crops of the full sensor, binning made visible, PSFs
at the capture's scale, and previews of what the sensor delivers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.io.exr import read_layer


@pytest.mark.render
def test_a_crop_equals_the_same_window_of_the_whole_frame():
    """Mitsuba's film crop: the window's pixels, the same camera, Monte Carlo apart."""
    base = {"scene": "train", "mode": "coded", "width": 256, "height": 192, "spp": 256}
    window = (40, 100, 64, 48)
    whole = render_capture(CaptureSpec.geometric(**base), progress=False).image
    crops = [
        render_capture(CaptureSpec.geometric(**base, crop=window, seed=s), progress=False).image
        for s in (1, 2)
    ]
    x, y, w, h = window
    same = whole[y : y + h, x : x + w]
    assert crops[0].shape == same.shape == (48, 64, 3)
    floor = np.abs(crops[1] - crops[0]).mean()  # two seeds: the Monte Carlo floor
    assert np.abs(same - crops[0]).mean() < 1.3 * floor
    assert abs(same.mean() / crops[0].mean() - 1) < 0.01
    other = whole[y + 20 : y + 20 + h, x + 30 : x + 30 + w]  # a window elsewhere differs
    assert np.abs(other - crops[0]).mean() > 3 * floor


def test_crop_must_lie_inside_the_sensor():
    for crop in ((0, 0, 1281, 10), (-1, 0, 10, 10), (0, 0, 1, 10), (0.5, 0, 10, 10)):
        with pytest.raises(ParameterError, match="`crop` must be X,Y,W,H"):
            CaptureSpec.geometric(width=1280, height=960, crop=crop)
    assert CaptureSpec.geometric(width=1280, height=960, crop=(1270, 950, 10, 10)).image_size == (
        10,
        10,
    )


@pytest.mark.render
def test_cli_crop_is_the_full_sensor_and_recorded(tmp_path, capsys):
    out = tmp_path / "c"
    argv = ["render", "train", "--crop", "300,500,48,32", "--spp", "128", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    text = capsys.readouterr()
    meta = json.loads((out / "capture.json").read_text())
    assert meta["crop"] == {
        "x": 300, "y": 500, "width": 48, "height": 32,
        "sensor_width_px": 1280, "sensor_height_px": 960,
    }  # fmt: skip
    assert meta["camera"]["width_px"] == 1280 and abs(meta["optics"]["r_px"] - 2.0) < 1e-9
    assert "48x32 window at (300, 500) of a 1280x960 sensor" in text.out
    assert "at 1280x960 px: r = 2 px" in text.out and "binned" not in text.err
    assert read_layer(out / "capture.exr", "capture").shape == (32, 48, 3)


@pytest.mark.render
def test_a_binned_sensor_says_so_with_its_scale(tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["render", "train", "--spp", "16", "--quiet", "--out", str(out)]) == 0
    text = capsys.readouterr()
    assert "at 320x240 px: r = 0.5 px" in text.out
    assert "binned 4x: the coded blur is sub-pixel (r = 0.5 px" in text.err
    assert "--crop X,Y,W,H" in text.err
    assert any("binned" in n for n in json.loads((out / "capture.json").read_text())["notes"])


@pytest.mark.render
def test_psf_like_a_capture_and_deconvolve_refuses_another_scale(tmp_path, capsys):
    cap = tmp_path / "c"
    argv = ["render", "train", "--width", "160", "--height", "120", "--spp", "16", "--quiet"]
    assert main([*argv, "--out", str(cap)]) == 0
    full, like = tmp_path / "full", tmp_path / "like"
    assert main(["psf", "--depth", "500", "--velocity", "0", "--out", str(full)]) == 0
    argv = ["psf", "--depth", "500", "--velocity", "0", "--like", str(cap / "capture.exr")]
    assert main([*argv, "--out", str(like)]) == 0
    made = json.loads((like / "psf.json").read_text())
    assert made["width_px"] == 160 and abs(made["r_px"] - 0.25) < 1e-9  # 2 px / 8
    capsys.readouterr()
    dec = ["deconvolve", str(cap / "capture.exr"), "--psf"]
    assert main([*dec, str(full / "psf_analytic.exr"), "--out", str(tmp_path / "x.exr")]) == 2
    err = capsys.readouterr().err
    assert "made for a 1280x960 sensor" in err and "the capture for 160x120" in err
    assert "--like" in err
    assert main([*dec, str(like / "psf_analytic.exr"), "--out", str(tmp_path / "y.exr")]) == 0
    np.save(tmp_path / "k.npy", np.ones((3, 3)))
    assert main([*dec, str(tmp_path / "k.npy"), "--out", str(tmp_path / "z.exr")]) == 0
    assert "records no sensor size" in capsys.readouterr().err


def test_psf_width_and_crop_flags(tmp_path):
    out = tmp_path / "p"
    argv = ["psf", "--depth", "500", "--velocity", "0", "--width", "640", "--height", "480"]
    assert main([*argv, "--crop", "10,20,100,50", "--out", str(out)]) == 0
    meta = json.loads((out / "psf.json").read_text())
    assert meta["width_px"] == 640 and abs(meta["r_px"] - 1.0) < 1e-9
    assert meta["crop"]["x"] == 10 and meta["crop"]["sensor_width_px"] == 640
    bad = ["psf", "--depth", "500", "--velocity", "0", "--like", "x.exr", "--width", "64"]
    assert main([*bad, "--out", str(tmp_path / "q")]) == 2


@pytest.mark.render
def test_a_sensor_capture_previews_its_noisy_layer(tmp_path):
    import imageio.v3 as iio

    from pacam_render.io.preview import srgb8

    out = tmp_path / "s"
    argv = ["render", "train", "--mode", "short", "--width", "32", "--height", "24"]
    argv += ["--spp", "8", "--sensor", "grasshopper-icx285", "--light-level", "30", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    png = iio.imread(out / "capture.png")
    noisy = read_layer(out / "capture.exr", "noisy")
    clean = read_layer(out / "capture.exr", "capture")
    lf = json.loads((out / "capture.json").read_text())["light_factor"]
    assert np.array_equal(png, srgb8(noisy, 1.0 / lf))
    assert not np.array_equal(png, srgb8(clean, 1.0 / lf))
