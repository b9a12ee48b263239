"""Issue 37's low items that deconvolve and the output folders meet, on hand-made files
(no rendering): a kernel file that does not sum to 1, NaN in ``sharp``, a capture named by its
folder, a dangling link as ``--out``, and a ``--passes`` that a noise target ignores."""

from __future__ import annotations

import argparse
import json
import warnings

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.io.exr import write_exr
from pacam_render.limits import PacamWarning
from pacam_render.model.camera import prototype


def _capture(folder, truth: bool, h: int = 40, w: int = 48):
    rng = np.random.default_rng(0)
    img = rng.random((h, w, 3)).astype(np.float32)
    layers = {"capture": img}
    if truth:
        layers.update(sharp=img, object_id=np.zeros((h, w), np.float32),
                      velocity=np.zeros((h, w, 2), np.float32))  # fmt: skip
    write_exr(folder / "capture.exr", layers)
    crop = {"x": 0, "y": 0, "width": w, "height": h, "sensor_width_px": 1280,
            "sensor_height_px": 960}  # fmt: skip
    meta = {"camera": prototype().inputs(), "mode": "coded", "crop": crop, "objects": {}}
    (folder / "capture.json").write_text(json.dumps(meta))
    return folder / "capture.exr"


@pytest.fixture
def cap(tmp_path):
    return _capture(tmp_path, truth=False)


@pytest.mark.parametrize("total", [25.0, 250.0])
def test_a_kernel_file_that_does_not_sum_to_1_gets_a_note(cap, tmp_path, capsys, total):
    k = np.zeros((3, 3))
    k[1, 1] = total
    np.save(tmp_path / "k.npy", k)
    argv = ["deconvolve", str(cap), "--psf", str(tmp_path / "k.npy"), "--method", "wiener"]
    assert main([*argv, "--noise-sigma", "0.01", "--out", str(tmp_path / "d")]) == 0
    assert f"sums to {total:g}, not 1: it is normalised" in capsys.readouterr().err


def test_a_kernel_file_that_sums_to_nothing_is_refused(cap, tmp_path, capsys):
    np.save(tmp_path / "k.npy", np.full((3, 3), 2.5e-29 / 9))
    argv = ["deconvolve", str(cap), "--psf", str(tmp_path / "k.npy"), "--method", "wiener"]
    # a kernel of 2.5e-29 is still a kernel (its largest value sets the scale): normalised
    assert main([*argv, "--noise-sigma", "0.01", "--out", str(tmp_path / "d")]) == 0
    np.save(tmp_path / "z.npy", np.array([[1.0, -1.0, 0.0]]))
    argv[3] = str(tmp_path / "z.npy")
    capsys.readouterr()
    assert main([*argv, "--noise-sigma", "0.01", "--out", str(tmp_path / "e")]) == 2
    assert "sums to 0: it holds no PSF" in capsys.readouterr().err


def test_an_allowed_mismatch_needs_a_folder_that_records_it(cap, tmp_path, capsys):
    """Issue 47 (low): with --out X.exr the allowed mismatch was said on stderr only."""
    k = np.zeros((3, 3))
    k[1, 1] = 1.0
    np.save(tmp_path / "k.npy", k)
    argv = ["deconvolve", str(cap), "--psf", str(tmp_path / "k.npy"), "--method", "wiener",
            "--noise-sigma", "0.01", "--allow-psf-mismatch"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "x.exr")]) == 2
    assert "--allow-psf-mismatch needs --out DIR" in capsys.readouterr().err
    assert not (tmp_path / "x.exr").exists()
    assert main([*argv, "--out", str(tmp_path / "d")]) == 0


def test_nan_in_sharp_is_no_score_not_a_nan_score(tmp_path, capsys, monkeypatch):
    import pacam_render.cli.deconvolve as cli_deconvolve
    from pacam_render.io.exr import read_exr

    cap = _capture(tmp_path, truth=True, h=96, w=128)

    def with_nan(path):  # EXR files refuse NaN on writing: a damaged file is read with one
        layers = read_exr(path)
        layers["sharp"][0, 0, 0] = np.nan
        return layers

    monkeypatch.setattr(cli_deconvolve, "read_exr", with_nan)
    argv = ["deconvolve", str(cap.parent), "--method", "wiener", "--noise-sigma", "0.01"]
    assert main([*argv, "--out", str(tmp_path / "d")]) == 0  # the folder names the capture
    out = capsys.readouterr()
    assert "holds NaN or inf: no score" in out.err and "PSNR nan" not in out.out
    assert "psnr_db" not in json.loads((tmp_path / "d" / "deconvolved.json").read_text())


def test_a_dangling_link_as_out_is_named(cap, tmp_path, capsys):
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "nowhere" / "x")
    assert main(["deconvolve", str(cap), "--out", str(link)]) == 2
    err = capsys.readouterr().err
    assert "is a link to" in err and "which does not exist" in err and "File exists" not in err


def test_passes_with_a_noise_target_gets_a_note():
    from pacam_render.cli.render import _passes

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PacamWarning)
        assert _passes(argparse.Namespace(passes=5), target=object()) == 5
        assert _passes(argparse.Namespace(passes=None), target=object()) == 2
        assert _passes(argparse.Namespace(passes=None), target=None) == 2
    assert len(caught) == 1 and "--passes 5 has no effect with a noise target" in str(
        caught[0].message
    )
