"""restore_capture is ``pacam deconvolve`` in one call (issue 56): the same layer, noise,
kernel, registration and score, whether given the capture in memory or as the command reads it
from its files. A bare deconvolve with one sigma (the how-to's old recipe) is not: it skips the
render's noise and the flat field, and its score differed (14.32 against 15.97 dB)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import pacam_render as pr
from pacam_render.cli import main
from pacam_render.exposure.direct import write_capture
from pacam_render.io.exr import read_exr
from pacam_render.restore.restoration import restore_capture
from pacam_render.sensor.apply import add_sensor_layers
from pacam_render.sensor.model import SensorModel

pytestmark = pytest.mark.render


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    spec = pr.CaptureSpec(scene="train", mode="coded", width=64, height=48, spp=16, seed=4,
                          diffraction="off")  # fmt: skip
    cap = pr.render_capture(spec, progress=False)
    add_sensor_layers(cap, SensorModel.from_preset("grasshopper-icx285"), "grasshopper-icx285",
                      300.0, 0)  # fmt: skip
    out = tmp_path_factory.mktemp("cap")
    write_capture(cap, out)
    return cap, out


def test_restore_capture_gives_the_commands_estimate_and_score(capture, tmp_path):
    cap, folder = capture
    assert main(["deconvolve", str(folder), "--method", "wiener", "--out",
                 str(tmp_path / "d")]) == 0  # fmt: skip
    cli = json.loads((tmp_path / "d" / "deconvolved.json").read_text())
    cli_est = read_exr(tmp_path / "d" / "deconvolved.exr")["deconvolved"]
    res = restore_capture(cap, method="wiener")  # in memory: the EXR's float32 aside, the same
    assert res.layer == "noisy" and res.noise["source"] == cli["noise_sigma_source"]
    assert res.score["psnr_db"] == pytest.approx(cli["psnr_db"], abs=0.01)
    assert res.score["psnr_moving_db"] == pytest.approx(cli["psnr_moving_db"], abs=0.01)
    assert np.allclose(res.estimate, cli_est, atol=1e-4)
    bare = pr.deconvolve(cap.extra_layers["noisy"], pr.analytic_psf(cap.record), "wiener",
                         noise_sigma=cap.record.known_noise_sigma)  # fmt: skip
    assert not np.allclose(bare, res.estimate, atol=1e-4)  # the old recipe is another answer
