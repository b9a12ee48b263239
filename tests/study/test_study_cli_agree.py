"""One honest answer (issue 46, item 1): a capture scored by ``pacam deconvolve`` and as a
one-point study agree by default, with no oracle; the oracle is opt-in and labelled, and
``pacam deconvolve --model-sigma`` with the oracle's value reproduces an oracle study's row.

The reference is the command line itself: the study renders the same capture (same spec and
seed, so the same pixels and the same sensor draw) and restores it through its own code path.
"""

from __future__ import annotations

import csv
import json

import pytest

from pacam_render.cli import main
from pacam_render.study import load_study, run_study

pytestmark = pytest.mark.render

WINDOW = ["--width", "1280", "--height", "960", "--crop", "200,560,160,96", "--spp", "32",
          "--max-step-px", "0.5", "--diffraction", "off", "--relative-illumination", "off",
          "--seed", "0"]  # fmt: skip
STUDY = """
[study]
name = "one"
report = "table"
{extra}
[render]
width = 1280
height = 960
crop = [200, 560, 160, 96]
spp = 32
max_step_px = 0.5
diffraction = "off"
relative_illumination = "off"
[grid]
mode = ["coded"]
light_level = [300.0]
method = ["hl"]
"""


def _study(tmp_path, name: str, extra: str = "") -> dict:
    path = tmp_path / f"{name}.toml"
    path.write_text(STUDY.format(extra=extra))
    out = tmp_path / name
    summary = run_study(load_study(str(path)), out, workers=0, progress=False)
    assert summary.failed == 0
    with open(out / "results.csv", newline="") as f:
        (row,) = list(csv.DictReader(f))
    return row


def _cli(tmp_path, *flags) -> dict:
    out = tmp_path / f"d{len(list(tmp_path.glob('d*')))}"
    assert main(["deconvolve", str(tmp_path / "cap" / "capture.exr"), "--out", str(out),
                 *flags]) == 0  # fmt: skip
    return json.loads((out / "deconvolved.json").read_text())


@pytest.fixture(scope="module")
def captured(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("agree")
    args = ["render", "train", "--mode", "coded", *WINDOW, "--sensor", "grasshopper-icx285",
            "--light-level", "300", "--quiet", "--out", str(tmp / "cap")]  # fmt: skip
    assert main(args) == 0
    return tmp


def test_the_cli_and_a_one_point_study_agree_by_default(captured):
    row = _study(captured, "none")
    cli = _cli(captured)
    assert row["model_error"] == "none"
    for key in ("psnr_db", "psnr_moving_db", "psnr_static_db"):
        assert float(row[key]) == pytest.approx(cli[key], abs=0.05), key
    assert cli["model_sigma"] == 0.0 and cli["render_noise_sigma"] > 0.0
    assert "Monte Carlo" in cli["noise_sigma_source"]


def test_the_oracle_is_opt_in_labelled_and_reproduced_by_a_given_model_sigma(captured):
    row = _study(captured, "oracle", 'model_error = "oracle"')
    assert row["model_error"] == "oracle" and float(row["model_sigma"]) > 0.0
    report = (captured / "oracle" / "report.md").read_text()
    assert "**oracle**" in report and "(oracle: told each capture's model error)" in report
    cli = _cli(captured, "--model-sigma", row["model_sigma"])
    assert float(row["psnr_moving_db"]) == pytest.approx(cli["psnr_moving_db"], abs=0.05)
    none = _cli(captured)
    assert abs(cli["psnr_moving_db"] - none["psnr_moving_db"]) > 0.05  # the oracle matters here
    assert float(row["psnr_moving_no_model_sigma_db"]) == pytest.approx(
        none["psnr_moving_db"], abs=0.05
    )


def test_a_model_sigma_is_checked_before_any_work(captured, capsys):
    code = main(["deconvolve", str(captured / "cap" / "capture.exr"), "--model-sigma", "-1",
                 "--out", str(captured / "bad")])  # fmt: skip
    assert code == 2 and "--model-sigma must be in [0, 10]" in capsys.readouterr().err
    assert not (captured / "bad").exists()
