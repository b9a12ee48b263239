"""Every method a study spec accepts restores its points (issue 37 item 5).

On main before the fix, the spec check accepted ``rl`` and ``uwiener`` and every such point
failed after its render (``richardson_lucy() got an unexpected keyword argument
'noise_sigma'``). ``rl`` also needs non-negative data, which a noisy layer is not (read noise);
the study and ``pacam deconvolve`` clip it at 0, the CLI with a note.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.restore.deconvolve import METHODS, SIGMA_METHODS, nonnegative_for

pytestmark = pytest.mark.render

SPEC = """
[study]
name = "methods"
report = "crossover"
[render]
width = 48
height = 36
spp = 4
max_step_px = 4.0
[grid]
mode = ["coded"]
light_level = [300.0]
method = ["rl", "uwiener", "wiener"]
"""


def test_rl_and_uwiener_points_are_restored_not_failed(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    assert main(["study", str(spec), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    with open(out / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert {r["method"]: r["status"] for r in rows} == dict.fromkeys(
        ("rl", "uwiener", "wiener"), "ok"
    )
    assert all(np.isfinite(float(r["psnr_db"])) for r in rows)


def test_the_sigma_methods_are_the_ones_that_take_a_sigma():
    import inspect

    from pacam_render.restore import deconvolve as d

    funcs = {"wiener": d.wiener, "rl": d.richardson_lucy, "uwiener": d.unsupervised_wiener,
             "bm3d": d.bm3d_deblur}  # fmt: skip
    for name, f in funcs.items():
        takes = "noise_sigma" in inspect.signature(f).parameters
        assert takes == (name in SIGMA_METHODS), name
    assert set(SIGMA_METHODS) <= set(METHODS)
    y = np.array([[-0.01, 0.5], [0.2, -1e-9]])
    clipped, n = nonnegative_for("rl", y)
    assert n == 2 and clipped.min() == 0.0 and clipped[0, 1] == 0.5
    assert nonnegative_for("hl", y)[0] is y


def test_deconvolve_rl_on_a_noisy_layer_clips_with_a_note(tmp_path, capsys):
    cap = tmp_path / "c"
    args = ["render", "train", "--width", "64", "--height", "48", "--spp", "4", "--quiet"]
    sensor = ["--sensor", "grasshopper-icx285", "--light-level", "30"]
    assert main([*args, *sensor, "--out", str(cap)]) == 0
    capsys.readouterr()
    assert main(["deconvolve", str(cap / "capture.exr"), "--method", "rl",
                 "--out", str(tmp_path / "d")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "rl needs non-negative data" in err and "clipped to 0" in err
