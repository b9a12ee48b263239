"""Issue 47 item 12: a finite LCoS contrast enters the light factor and the analytic kernel as
it enters the rays (1/C of the light on the rest of the lens), so the capture reads right on
the white scale and deconvolves as the ideal LCoS's does."""

from __future__ import annotations

import json

import pytest

from pacam_render.cli import main

ARGS = ["render", "train", "--width", "64", "--height", "48", "--spp", "8", "--diffraction",
        "off", "--quiet"]  # fmt: skip


def _capture(tmp_path, name, *extra):
    out = tmp_path / name
    assert main([*ARGS, *extra, "--out", str(out)]) == 0
    return out, json.loads((out / "capture.json").read_text())


def _psnr(tmp_path, cap, name):
    out = tmp_path / name
    assert main(["deconvolve", str(cap / "capture.exr"), "--psf", "analytic", "--method",
                 "wiener", "--out", str(out)]) == 0  # fmt: skip
    return json.loads((out / "deconvolved.json").read_text())["psnr_db"]


@pytest.mark.render
def test_a_leaky_lcos_is_in_the_light_factor_and_the_kernel(tmp_path):
    ideal, m0 = _capture(tmp_path, "ideal")
    leaky, m20 = _capture(tmp_path, "c20", "--lcos-contrast", "20")
    exposure = m0["exposure_ms"] / m0["reference_exposure_ms"]  # the whole lens's share
    want = (1 - 1 / 20) * m0["light_factor"] + exposure / 20  # closed form: 1/C of the rest
    assert m20["light_factor"] == pytest.approx(want, rel=1e-6)
    p0 = _psnr(tmp_path, ideal, "d0")
    p20 = _psnr(tmp_path, leaky, "d20")
    assert p20 > p0 - 1.0  # was 18.6 against 29.0 dB with the ideal LCoS's kernel and scale
