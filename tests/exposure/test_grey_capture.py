"""Grey captures end to end (issue 35 item 5): the mono variant, through ``PACAM_VARIANT`` or
``--grey``, renders, writes capture.exr/.png/.json, resumes, and its ray-traced PSF renders.

On main before this issue, ``PACAM_VARIANT=llvm_ad_mono pacam render`` rendered and then died
writing the PNG (an (H, W, 1) image), leaving a ``.partial`` and no JSON, and ``pacam psf
--render`` died on an RGB radiance. Kept tiny: 32x24 px at 8 spp, and one 31x31 PSF.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.exposure.direct import CaptureInterrupted, render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.io.exr import read_exr
from pacam_render.render.variant import llvm_status

pytestmark = pytest.mark.render
TINY = ["train", "--mode", "coded", "--width", "32", "--height", "24", "--spp", "8", "--quiet"]
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture(autouse=True)
def _restore_variant():
    """A grey test leaves the process's variant as it found it (later tests expect RGB)."""
    import mitsuba as mi

    before = mi.variant()
    yield
    if before is not None and mi.variant() != before:
        mi.set_variant(before)


def _needs_llvm():
    ok, why = llvm_status()
    if not ok:
        pytest.skip(f"llvm_ad_mono needs the LLVM backend: {why}")


def _pacam(*argv, variant: str | None = None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PACAM_VARIANT"}
    if variant is not None:
        env["PACAM_VARIANT"] = variant
    cmd = [sys.executable, "-m", "pacam_render", *argv]
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def mono_capture(tmp_path_factory):
    """``PACAM_VARIANT=llvm_ad_mono pacam render``, in its own process (seed 3)."""
    _needs_llvm()
    out = tmp_path_factory.mktemp("grey") / "mono"
    done = _pacam("render", *TINY, "--seed", "3", "--out", str(out), variant="llvm_ad_mono")
    assert done.returncode == 0, done.stderr
    return out


def test_mono_variant_render_writes_png_and_json(mono_capture):
    import imageio.v3 as iio

    files = sorted(p.name for p in mono_capture.iterdir())  # and no .partial left behind
    assert files == ["capture.exr", "capture.json", "capture.png"]
    rec = json.loads((mono_capture / "capture.json").read_text())
    assert rec["variant"] == "llvm_ad_mono" and rec["spec"]["grey"] is True
    assert rec["render_error"]["mc_sigma"] > 0
    layers = read_exr(mono_capture / "capture.exr")
    for name in ("capture", "sharp", "depth", "object_id"):
        assert layers[name].shape == (24, 32), name
    assert layers["velocity"].shape == (24, 32, 2)
    assert iio.imread(mono_capture / "capture.png").shape == (24, 32)


def test_grey_flag_is_the_mono_variant_and_the_luminance_of_rgb(mono_capture, tmp_path):
    """``--grey`` in this process renders what ``PACAM_VARIANT=llvm_ad_mono`` rendered in
    another, bit for bit; and grey is the luminance of the colour capture (Mitsuba's mono
    variant takes the luminance of every reflectance), within the Monte Carlo error."""
    grey, colour = tmp_path / "grey", tmp_path / "colour"
    assert main(["render", *TINY, "--seed", "3", "--grey", "--out", str(grey)]) == 0
    ours, theirs = read_exr(grey / "capture.exr"), read_exr(mono_capture / "capture.exr")
    np.testing.assert_array_equal(ours["capture"], theirs["capture"])
    assert main(["render", *TINY, "--seed", "3", "--out", str(colour)]) == 0
    rgb = read_exr(colour / "capture.exr")
    y = rgb["sharp"] @ LUMINANCE
    assert ours["sharp"].mean() == pytest.approx(y.mean(), rel=0.02)
    assert json.loads((colour / "capture.json").read_text())["variant"] == "llvm_ad_rgb"


def test_grey_capture_resumes_from_its_checkpoint(tmp_path):
    """The checkpoint's image shape is the grey (H, W): a stopped grey capture resumes."""
    _needs_llvm()
    spec = CaptureSpec.geometric(
        scene="train", mode="coded", width=32, height=24, spp=8, seed=7, grey=True
    )
    full = render_capture(spec, progress=False, truth=False)
    part = tmp_path / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=3, truth=False)
    resumed = render_capture(spec, partial_dir=part, progress=False, truth=False)
    assert resumed.meta["resumed_from_step"] == 3 and resumed.image.shape == (24, 32)
    assert np.array_equal(resumed.image, full.image)
    assert spec.key() != CaptureSpec.geometric(**{**spec.__dict__, "grey": False}).key()


def test_grey_with_an_rgb_variant_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PACAM_VARIANT", "llvm_ad_rgb")
    out = tmp_path / "x"
    assert main(["render", *TINY, "--grey", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--grey" in err and "PACAM_VARIANT='llvm_ad_rgb'" in err and "llvm_ad_mono" in err
    assert not out.exists()


def test_a_bayer_sensor_on_a_grey_render_is_refused_before_rendering(tmp_path, capsys):
    out = tmp_path / "x"
    argv = ["render", *TINY, "--grey", "--sensor", "grasshopper-icx285", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "grasshopper-icx285-mono" in err and "Traceback" not in err
    assert not out.exists()


def test_mono_psf_render_exits_0(tmp_path):
    """``PACAM_VARIANT=llvm_ad_mono pacam psf --render``: the emitter's radiance is set in the
    variant's own type (a Float in mono, not a Color3f)."""
    _needs_llvm()
    out = tmp_path / "psf"
    argv = ["psf", "--depth", "500", "--velocity", "0.5", "--width", "320", "--height", "240"]
    done = _pacam(*argv, "--render", "--spp", "16", "--quiet", "--out", str(out),
                  variant="llvm_ad_mono")  # fmt: skip
    assert done.returncode == 0, done.stderr
    rendered = json.loads((out / "psf.json").read_text())["rendered"]
    assert rendered["variant"] == "llvm_ad_mono" and rendered["l1_vs_analytic"] < 0.05
    grey = tmp_path / "grey"
    assert main([*argv, "--render", "--spp", "16", "--quiet", "--grey", "--out", str(grey)]) == 0
    a, b = (read_exr(d / "psf_rendered.exr")["psf"] for d in (out, grey))
    np.testing.assert_allclose(a, b, atol=1e-6)
