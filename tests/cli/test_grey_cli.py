"""``pacam sensor`` and ``pacam deconvolve`` on a grey capture (issue 35 item 5).

On main before this issue a grey (H, W) capture went through the colour ICX285 as if it were a
raw Bayer mosaic (and came back demosaicked into false colour), and ``deconvolve`` died
scoring it (``truth.shape[2]``). Now the Bayer preset is refused, naming the monochrome one,
and the monochrome preset and every restoration work on one channel.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.io.exr import read_exr
from pacam_render.render.variant import llvm_status

pytestmark = pytest.mark.render
MONO = "grasshopper-icx285-mono"
TINY = ["train", "--mode", "coded", "--width", "32", "--height", "24", "--spp", "8", "--quiet"]


@pytest.fixture(scope="module")
def grey_capture(tmp_path_factory):
    """A --grey capture (no sensor), the process's variant restored afterwards."""
    import mitsuba as mi

    ok, why = llvm_status()
    if not ok:
        pytest.skip(f"needs the LLVM backend: {why}")
    before = mi.variant()
    out = tmp_path_factory.mktemp("grey_cli") / "grey"
    try:
        assert main(["render", *TINY, "--grey", "--out", str(out)]) == 0
    finally:
        if before is not None:
            mi.set_variant(before)
    return out


def test_sensor_refuses_a_bayer_preset_on_a_grey_capture(grey_capture, tmp_path, capsys):
    out = tmp_path / "bayer"
    argv = ["sensor", str(grey_capture), "--sensor", "grasshopper-icx285", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"--sensor {MONO}" in err and "grey" in err and "Traceback" not in err
    assert not (out / "capture.exr").exists()


def test_sensor_and_deconvolve_on_a_grey_capture(grey_capture, tmp_path, capsys):
    sensed, restored = tmp_path / "sensed", tmp_path / "restored"
    argv = ["sensor", str(grey_capture), "--sensor", MONO, "--light-level", "3000"]
    assert main([*argv, "--out", str(sensed), "--quiet"]) == 0
    layers = read_exr(sensed / "capture.exr")
    assert layers["raw"].shape == layers["noisy"].shape == (24, 32)  # no mosaic, no demosaic
    rec = json.loads((sensed / "capture.json").read_text())
    assert rec["sensor"]["model"]["bayer"] is None and rec["noise_sigma"] > 0
    noise = layers["noisy"] - layers["capture"]
    assert np.std(noise) == pytest.approx(rec["noise_sigma"], rel=0.5)
    for method in ("hl", "wiener"):
        out = restored / method
        assert main(["deconvolve", str(sensed / "capture.exr"), "--method", method,
                     "--out", str(out)]) == 0  # fmt: skip
        est = read_exr(out / "deconvolved.exr")
        assert next(iter(est.values())).shape == (24, 32)
        score = json.loads((out / "deconvolved.json").read_text())
        assert np.isfinite(score["psnr_db"]) and 0 < score["ssim"] <= 1
    assert "score against sharp" in capsys.readouterr().out
