"""EXR I/O, safe outputs, and the psf / deconvolve commands end to end."""

import json

import numpy as np
import pytest
from scipy.signal import fftconvolve
from skimage import data

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.io import exr as exrio
from pacam_render.model.camera import CameraDesign, prototype
from pacam_render.psf import analytic as psf
from pacam_render.restore.deconvolve import psnr


def test_exr_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(3)
    layers = {"capture": rng.random((6, 7, 3)).astype(np.float32), "depth": rng.random((6, 7))}
    p = exrio.write_exr(tmp_path / "a.exr", layers)
    back = exrio.read_exr(p)
    assert np.array_equal(back["capture"], layers["capture"])
    assert np.array_equal(back["depth"], layers["depth"].astype(np.float32))


def test_exr_errors(tmp_path):
    p = exrio.write_exr(tmp_path / "a.exr", {"capture": np.zeros((4, 4))})
    with pytest.raises(ParameterError, match="already exists"):
        exrio.write_exr(p, {"capture": np.ones((4, 4))})
    assert exrio.read_layer(p, "capture").max() == 0.0  # the refused write changed nothing
    with pytest.raises(ParameterError, match="no layer 'psf'; it has: capture"):
        exrio.read_layer(p, "psf")
    bad = tmp_path / "bad.exr"
    bad.write_bytes(b"not an exr at all")
    with pytest.raises(ParameterError, match="not a readable OpenEXR"):
        exrio.read_exr(bad)
    with pytest.raises(ParameterError, match="NaN"):
        exrio.write_exr(tmp_path / "n.exr", {"x": np.full((2, 2), np.nan)})
    assert not (tmp_path / "n.exr").exists()
    assert [f.name for f in tmp_path.iterdir() if f.name.startswith(".")] == []  # no temp left


def test_camera_inputs_round_trip():
    cam = prototype()
    assert CameraDesign.from_inputs(json.loads(json.dumps(cam.inputs()))) == cam
    with pytest.raises(ParameterError, match="unknown camera parameters"):
        CameraDesign.from_inputs({"bogus": 1})


def test_cli_psf_writes_registered_kernel(tmp_path, capsys):
    out = tmp_path / "p"
    assert (
        main(["psf", "--depth", "500", "--velocity", "0.5", "--size", "51", "--out", str(out)]) == 0
    )
    k = exrio.read_layer(out / "psf_analytic.exr", "psf")
    meta = json.loads((out / "psf.json").read_text())
    ref = psf.discrete_coded_psf(0.5, meta["a_i_px_per_ms2"], meta["r_px"], 22.5, 16, size=51)
    assert k.shape == (51, 51) and np.allclose(k, ref, atol=1e-7)
    for key in (
        "r_px",
        "beta_px_per_mm",
        "a_i_px_per_ms2",
        "R_mm",
        "focus_distance_mm",
        "fov_deg",
        "width_px",
    ):
        assert key in meta
    assert main(["psf", "--depth", "500", "--velocity", "0.5", "--out", str(out)]) == 2
    assert "already holds results" in capsys.readouterr().err
    assert main(["psf", "--depth", "-5", "--velocity", "0.5", "--out", str(tmp_path / "q")]) == 2
    assert (
        main(
            [
                "psf",
                "--depth",
                "500",
                "--velocity",
                "0",
                "--size",
                "4",
                "--out",
                str(tmp_path / "q"),
            ]
        )
        == 2
    )


def test_cli_deconvolve_analytic(tmp_path, capsys):
    cam = prototype()
    x = data.camera()[::4, ::4] / 255.0
    k = psf.design_psf(cam, "coded", 0.0, origin="pinhole")  # as the CLI registers it
    pad = k.shape[0]
    y = fftconvolve(np.pad(x, pad, mode="reflect"), k, mode="same")[pad:-pad, pad:-pad]
    y = y + np.random.default_rng(0).normal(0, 0.01, y.shape)
    cap = tmp_path / "capture.exr"
    exrio.write_exr(cap, {"capture": y})
    (tmp_path / "capture.json").write_text(
        json.dumps(
            {"camera": cam.inputs(), "mode": "coded", "noise_sigma": 0.01, "crop": _window(y)}
        )  # fmt: skip
    )
    out = tmp_path / "deblurred.exr"
    assert main(["deconvolve", str(cap), "--psf", "analytic", "--out", str(out)]) == 0
    est = exrio.read_layer(out, "deconvolved")
    assert psnr(est, x) > psnr(y, x) + 3.0
    # errors: missing layer, missing file, wrong suffix, no overwrite
    assert main(["deconvolve", str(cap), "--layer", "nope", "--out", str(tmp_path / "o.exr")]) == 2
    assert "no layer 'nope'" in capsys.readouterr().err
    assert (
        main(["deconvolve", str(tmp_path / "missing.exr"), "--out", str(tmp_path / "o.exr")]) == 2
    )
    assert main(["deconvolve", str(cap), "--out", str(tmp_path / "o.txt")]) == 2
    assert main(["deconvolve", str(cap), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err


def test_cli_deconvolve_psf_from_file(tmp_path):
    x = data.camera()[::8, ::8] / 255.0
    k = psf.pillbox_psf(2.0, size=7)
    y = fftconvolve(np.pad(x, 7, mode="reflect"), k, mode="same")[7:-7, 7:-7]
    exrio.write_exr(tmp_path / "c.exr", {"capture": y})
    np.save(tmp_path / "k.npy", k)
    out = tmp_path / "d.png"
    assert (
        main(
            [
                "deconvolve",
                str(tmp_path / "c.exr"),
                "--psf",
                str(tmp_path / "k.npy"),
                "--method",
                "rl",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert out.stat().st_size > 0


@pytest.mark.render
def test_cli_deconvolve_uses_the_noise_a_sensor_capture_recorded(tmp_path, capsys):
    """pacam render --sensor records the sensor's noise; pacam deconvolve then deblurs the noisy
    layer with it, without being told. The paper preset's noise is sigma = 0.01 of white
    (Sec. 3), an independent reference for the recorded value."""
    cap = tmp_path / "cap"
    args = ["render", "train", "--mode", "coded", "--width", "48", "--height", "36"]
    args += ["--relative-illumination", "off"]  # radiance: no flat field to divide the sigma
    assert main([*args, "--spp", "4", "--sensor", "paper", "--out", str(cap), "--quiet"]) == 0
    meta = json.loads((cap / "capture.json").read_text())
    assert meta["noise_sigma"] == pytest.approx(0.01 * meta["light_factor"], rel=0.02)
    assert meta["noise_sigma_unit"].startswith("radiance x light_factor")
    capsys.readouterr()
    out = tmp_path / "d.exr"
    cmd = ["deconvolve", str(cap / "capture.exr"), "--method", "wiener", "--out", str(out)]
    assert main(cmd) == 0
    said = capsys.readouterr().out
    # the sensor's sigma and the render's Monte Carlo sigma, in quadrature (issue 46)
    mc = meta["render_error"]["mc_sigma_white_units"] * meta["light_factor"]
    told = np.hypot(meta["noise_sigma"], mc)
    assert "layer noisy" in said and f"noise sigma {told:.4g}" in said
    assert np.isfinite(exrio.read_exr(out)["deconvolved"]).all()
    # the default (hl) weights the data by the sensor's own noise model, which at the paper
    # preset is white with the same sigma
    from pacam_render.capture.record import CaptureRecord
    from pacam_render.restore.capture_noise import layer_noise

    noise = layer_noise(CaptureRecord.from_json(meta))
    assert noise.shot == 0 and np.sqrt(noise.floor) == pytest.approx(meta["noise_sigma"], rel=0.02)
    out1 = tmp_path / "d1.exr"
    assert main(["deconvolve", str(cap / "capture.exr"), "--out", str(out1)]) == 0
    assert "(hl, layer noisy, noise the sensor's Poisson-Gaussian noise" in capsys.readouterr().out
    # the noiseless layer, asked for by name, is not given the sensor's noise
    out2 = tmp_path / "d2.exr"
    cmd = ["deconvolve", str(cap / "capture.exr"), "--layer", "capture", "--out", str(out2)]
    assert main(cmd) == 0
    assert "layer capture, noise estimated" in capsys.readouterr().out


def test_cli_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"pacam {version('pacam_render')}"


def test_cli_output_to_a_closed_pipe_is_quiet():
    """`pacam design | head`: the reader leaves early; no BrokenPipe traceback."""
    import subprocess
    import sys

    code = "import sys; from pacam_render.cli import main; sys.exit(main(['design']))"
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    proc.stdout.close()  # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0
    assert "Traceback" not in err and "BrokenPipe" not in err


def test_outputs_get_the_umask_permissions(tmp_path):
    """Results are created with the process umask's mode, not mkstemp's 0600."""
    import os
    import stat

    from pacam_render.io.outputs import write_text

    old = os.umask(0o027)
    try:
        p = write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == 0o640


def test_cli_deconvolve_psf_file_beside_a_json_without_camera(tmp_path, capsys):
    """Only --psf analytic needs the capture's camera; a PSF file works beside any sidecar."""
    y = np.random.default_rng(1).uniform(0.2, 0.8, (40, 40))
    cap = tmp_path / "capture.exr"
    exrio.write_exr(cap, {"capture": y})
    (tmp_path / "capture.json").write_text(json.dumps({"note": "hand-made"}))
    k = np.zeros((5, 5))
    k[2, 1:4] = 1 / 3
    np.save(tmp_path / "k.npy", k)
    out = tmp_path / "d.exr"
    cmd = ["deconvolve", str(cap), "--psf", str(tmp_path / "k.npy"), "--out", str(out)]
    assert main(cmd) == 0
    assert "lacks 'mode' and 'camera'" in capsys.readouterr().err
    assert np.isfinite(exrio.read_exr(out)["deconvolved"]).all()
    bad = ["deconvolve", str(cap), "--psf", "analytic", "--out", str(tmp_path / "e.exr")]
    assert main(bad) == 2


def test_read_capture_divides_the_capture_layers_by_the_light_factor(tmp_path):
    """A hand-made capture: exactly its capture-unit layers are divided, and nothing else."""
    from pacam_render import read_capture
    from pacam_render.capture.record import LAYER_UNITS, WHITE_UNIT

    rng = np.random.default_rng(2)
    img = rng.random((4, 5, 3)).astype(np.float32)
    layers = {"capture": img, "noisy": img, "sub03": img, "sharp": img, "raw": img}
    exrio.write_exr(tmp_path / "capture.exr", {**layers, "depth": img[..., 0]})
    meta = {"camera": prototype().inputs(), "mode": "coded", "light_factor": 0.25,
            "crop": _window(img)}  # fmt: skip
    (tmp_path / "capture.json").write_text(json.dumps(meta))
    got = read_capture(tmp_path)  # the folder works as well as the file
    for name in ("capture", "noisy", "sub03"):
        assert np.allclose(got.layers[name], img * 4, rtol=1e-6) and got.units[name] == WHITE_UNIT
    for name in ("sharp", "raw"):
        assert np.array_equal(got.layers[name], img)
    assert got.units["raw"] == LAYER_UNITS["raw"] and got.units["sharp"] == WHITE_UNIT
    assert np.array_equal(got.layers["depth"], img[..., 0]) and got.record.light_factor == 0.25
    (tmp_path / "capture.json").write_text(json.dumps({**meta, "light_factor": 0.0}))
    with pytest.raises(ParameterError, match="light_factor"):
        read_capture(tmp_path / "capture.exr")
    (tmp_path / "capture.json").unlink()
    with pytest.raises(ParameterError, match="capture.json"):
        read_capture(tmp_path / "capture.exr")


@pytest.fixture(scope="module")
def coded_capture(tmp_path_factory):
    """A small coded capture of the train with its ground truth (rendered once, 3-6 s), in
    radiance: these tests check units and scales (flat-fielding a relative illumination is
    tested in tests/exposure/test_capture_illumination.py)."""
    out = tmp_path_factory.mktemp("coded") / "cap"
    args = ["render", "train", "--mode", "coded", "--width", "160", "--height", "120"]
    args += ["--relative-illumination", "off"]
    assert main([*args, "--spp", "16", "--out", str(out), "--quiet"]) == 0
    return out / "capture.exr"


@pytest.mark.render
def test_a_capture_records_its_units_and_reads_back_on_one_scale(coded_capture):
    """capture.json names each layer's unit; read_capture puts capture and sharp on one scale:
    the coded capture and the pinhole image collect the same light over the frame (their means
    agree within 2 %), where the file's layers differ by light_factor (0.08)."""
    from pacam_render import read_capture

    meta = json.loads(coded_capture.with_suffix(".json").read_text())
    raw = exrio.read_exr(coded_capture)
    assert set(meta["units"]) == set(raw)
    assert meta["units"]["capture"].startswith("radiance x light_factor")
    assert meta["units"]["sharp"].startswith("radiance (")
    lf = meta["light_factor"]
    assert raw["capture"].mean() / raw["sharp"].mean() == pytest.approx(lf, rel=0.02)
    got = read_capture(coded_capture)
    assert got.layers["capture"].mean() == pytest.approx(got.layers["sharp"].mean(), rel=0.02)
    assert np.allclose(got.layers["capture"], raw["capture"] / lf, rtol=1e-6)
    assert np.array_equal(got.layers["velocity"], raw["velocity"])
    assert set(got.units.values()) >= {meta["units"]["sharp"]}


def _blurred_camera_capture(folder, sigma=0.01):
    """The camera photograph blurred by the prototype's coded PSF, registered on the pinhole
    image as a rendered capture is, with white noise of ``sigma``; returns (capture, truth)."""
    cam = prototype()
    x = data.camera()[::4, ::4] / 255.0
    k = psf.design_psf(cam, "coded", 0.0, origin="pinhole")
    pad = k.shape[1]
    y = fftconvolve(np.pad(x, pad, mode="reflect"), k, mode="same")[pad:-pad, pad:-pad]
    y = y + np.random.default_rng(0).normal(0, sigma, y.shape)
    cap = folder / "capture.exr"
    exrio.write_exr(cap, {"capture": y})
    meta = {"camera": cam.inputs(), "mode": "coded", "noise_sigma": sigma, "crop": _window(y)}
    (folder / "capture.json").write_text(json.dumps(meta))
    return cap, x


def _best_shift(est, truth, reach=8):
    """The whole-pixel horizontal shift d that best aligns est[:, c + d] with truth[:, c]."""
    m = reach + 12
    inner = truth[m:-m, m:-m]
    errs = [
        np.mean((est[m:-m, m + d : est.shape[1] - m + d] - inner) ** 2)
        for d in range(-reach, reach + 1)
    ]
    return int(np.argmin(errs)) - reach


@pytest.mark.parametrize("method", ["wiener", "hl"])
def test_a_t0_psf_file_is_moved_onto_the_capture_registration(tmp_path, method):
    """pacam psf centres its kernel on the t = 0 image by default, 5 px (-a_i T^2 / 4) from the
    pinhole image a capture is registered on. psf.json records both; deconvolve moves the
    result back, so it lands where --psf analytic lands (best shift 0 against the truth, not
    5) and the two images agree within 2 % (mean absolute difference over the mean)."""
    cap, truth = _blurred_camera_capture(tmp_path)
    assert main(["psf", "--depth", "500", "--velocity", "0", "--out", str(tmp_path / "P")]) == 0
    meta = json.loads((tmp_path / "P" / "psf.json").read_text())
    closed_form = -0.25 * meta["a_i_px_per_ms2"] * meta["T_ms"] ** 2
    assert meta["origin"] == "t0" and meta["t0_offset_px"] == pytest.approx(closed_form)
    assert 4.5 < closed_form < 5.5
    kernel = tmp_path / "P" / "psf_analytic.exr"
    runs = {"file": ["--psf", str(kernel)], "analytic": ["--psf", "analytic"]}
    est = {}
    for name, flags in runs.items():
        out = tmp_path / name
        assert main(["deconvolve", str(cap), *flags, "--method", method, "--out", str(out)]) == 0
        est[name] = exrio.read_layer(out / "deconvolved.exr", "deconvolved")
    assert json.loads((tmp_path / "file" / "deconvolved.json").read_text())["psf"]["origin"] == "t0"
    from pacam_render.restore.deconvolve import deconvolve

    as_is = deconvolve(exrio.read_layer(cap, "capture"), exrio.read_layer(kernel, "psf"), method,
                       noise_sigma=0.01)  # fmt: skip
    assert _best_shift(as_is, truth) == 5  # what deconvolve did before it read the origin
    assert _best_shift(est["file"], truth) == _best_shift(est["analytic"], truth) == 0
    mad = np.abs(est["file"] - est["analytic"]).mean() / np.abs(est["analytic"]).mean()
    assert mad < 0.02


def test_to_pinhole_moves_by_minus_the_offset():
    """A t0 result moves by -t0_offset_px (a whole-pixel move is exact); pinhole stays."""
    from pacam_render.psf.origin import to_pinhole

    img = np.random.default_rng(4).random((9, 20, 3))
    moved = to_pinhole(img, "t0", 3.0)
    assert np.allclose(moved[:, :-3], img[:, 3:])
    assert to_pinhole(img, "pinhole", 3.0) is img
    with pytest.raises(ParameterError, match="origin must be one of t0, pinhole"):
        to_pinhole(img, "centre", 3.0)


@pytest.mark.render
def test_psf_like_a_capture_deconvolves_as_the_analytic_psf(coded_capture, tmp_path, capsys):
    """The README's path (pacam psf --like, then deconvolve --psf that file) gives the image of
    --psf analytic (issue 27: it was 5 px off at full scale, 14 % apart here)."""
    kernel = tmp_path / "P"
    like = ["psf", "--like", str(coded_capture), "--depth", "500", "--velocity", "0"]
    assert main([*like, "--out", str(kernel)]) == 0
    assert json.loads((kernel / "psf.json").read_text())["origin"] == "pinhole"
    est = {}
    for name, spec in (("X", str(kernel / "psf_analytic.exr")), ("A", "analytic")):
        cmd = ["deconvolve", str(coded_capture), "--psf", spec, "--method", "wiener"]
        assert main([*cmd, "--out", str(tmp_path / name)]) == 0
        est[name] = exrio.read_layer(tmp_path / name / "deconvolved.exr", "deconvolved")
    mad = np.abs(est["X"] - est["A"]).mean() / np.abs(est["A"]).mean()
    assert mad < 0.02
    meta = json.loads((tmp_path / "X" / "deconvolved.json").read_text())
    assert np.isfinite(meta["psnr_db"]) and "score against sharp: PSNR" in capsys.readouterr().out


@pytest.mark.render
def test_deconvolve_out_dir_records_and_scores(coded_capture, tmp_path, capsys):
    """--out DIR writes deconvolved.exr, .png (exposed like capture.png) and .json; the score
    is the deconvolved image / light_factor against sharp: its still-background PSNR matches
    one computed here from the layers (no shift), and it beats the blurred capture's."""
    out = tmp_path / "X"
    cmd = ["deconvolve", str(coded_capture), "--psf", "analytic", "--method", "wiener"]
    assert main([*cmd, "--out", str(out)]) == 0
    assert "score against sharp" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == [
        "deconvolved.exr",
        "deconvolved.json",
        "deconvolved.png",
    ]
    meta = json.loads((out / "deconvolved.json").read_text())
    assert meta["method"] == "wiener" and meta["psf"]["source"] == "analytic"
    assert meta["psf"]["origin"] == "pinhole" and meta["seconds"] > 0
    assert meta["noise_sigma"] > 0 and meta["noise_sigma_source"].startswith("estimated")
    assert meta["units"]["deconvolved"].startswith("radiance x light_factor")
    layers = exrio.read_exr(coded_capture)
    est = exrio.read_layer(out / "deconvolved.exr", "deconvolved") / meta["light_factor"]
    ids, speed = layers["object_id"], np.abs(layers["velocity"]).max(axis=-1)
    moving = np.isin(ids, np.unique(ids[speed > 0]))
    m = 4  # the shift search at 160 px; its columns at each side are left out
    still = ~moving
    still[:, :m] = still[:, -m:] = False

    def still_psnr(img):
        return 10 * np.log10(1 / np.mean((img[still] - layers["sharp"][still]) ** 2))

    assert meta["psnr_static_db"] == pytest.approx(still_psnr(est), abs=1e-3)
    assert meta["psnr_static_db"] > still_psnr(layers["capture"] / meta["light_factor"])
    assert set(meta["psnr_by_object"]) >= {"near_train", "backdrop"} and 0 < meta["ssim"] < 1
    import imageio.v3 as iio

    shown = [
        iio.imread(p).mean() for p in (out / "deconvolved.png", coded_capture.with_suffix(".png"))
    ]
    assert shown[0] == pytest.approx(shown[1], rel=0.05)
    # never overwritten without --force, never onto the input; a file path still works
    assert main([*cmd, "--out", str(out)]) == 2
    assert "already holds results" in capsys.readouterr().err
    assert main([*cmd, "--out", str(out), "--force"]) == 0
    assert main([*cmd, "--out", str(coded_capture), "--force"]) == 2
    assert "is an input" in capsys.readouterr().err
    assert main([*cmd, "--out", str(tmp_path / "d.exr")]) == 0
    assert "writes the image only" in capsys.readouterr().err


def _window(image) -> dict:
    """The JSON ``crop`` of a hand-made capture: a window of the prototype's full sensor (its
    px scale) the image's size, as a rendered ``--crop`` capture records it."""
    h, w = np.shape(image)[:2]
    return {"x": 0, "y": 0, "width": w, "height": h, "sensor_width_px": 1280,
            "sensor_height_px": 960}  # fmt: skip
