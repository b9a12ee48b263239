"""Issue 25 in the studies: each render meets its noise target, the model error the
deconvolver is told is measured (checked here against synthetic captures of known error), a
budget is enforced from pilot passes, and the plots carry confidence intervals."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy.stats import t as student

from pacam_render.errors import ParameterError
from pacam_render.restore.model_error import convolve, model_sigma
from pacam_render.study import load_study, run_study
from pacam_render.study.report import curves_ci

TINY = """
[study]
name = "tiny"
report = "crossover"
decompose = true
[render]
width = 48
height = 36
max_step_px = 4.0
noise_ratio = 0.2
[grid]
mode = ["coded", "short"]
light_level = [30.0, 3000.0]
"""


def _rows(out):
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


# --- the model error -----------------------------------------------------------------------------
def _scene(rng):
    sharp = rng.uniform(0.2, 0.8, size=(40, 60, 3))
    ids = np.ones((40, 60), int)
    ids[15:25, 20:40] = 2  # a "moving" object
    return sharp, ids, {"1": "wall", "2": "ball"}


def test_model_sigma_of_an_exact_model_is_zero_and_a_known_error_is_recovered():
    rng = np.random.default_rng(1)
    sharp, ids, objects = _scene(rng)
    k = np.zeros((5, 5))
    k[2, 1:4] = 1 / 3
    y = convolve(sharp, k)
    args = (ids, objects, {"ball"}, 6)
    assert model_sigma(y, sharp, k, *args, 0.0, 0.0) == pytest.approx(0.0, abs=1e-9)
    # the ball moved 3 px: a motion-invariant PSF shift, which the best shift absorbs
    moved = y.copy()
    moved[15:25, 23:43] = y[15:25, 20:40]
    moved[15:25, 20:23] = y[15:25, 17:20]
    assert model_sigma(moved, sharp, k, *args, 0.0, 0.0) < 0.05
    # an error of known size: 0.01 of white noise is recovered, and taken out when it is noise
    bumped = y + rng.normal(0, 0.01, y.shape)
    assert model_sigma(bumped, sharp, k, *args, 0.0, 0.0) == pytest.approx(0.01, rel=0.05)
    assert model_sigma(bumped, sharp, k, *args, 1e-4, 0.0) == pytest.approx(0.0, abs=2e-3)
    # noise in the sharp layer, blurred by k, is taken out too
    noisy_sharp = sharp + rng.normal(0, 0.02, sharp.shape)
    assert model_sigma(y, noisy_sharp, k, *args, 0.0, 0.02**2) < 2e-3
    assert model_sigma(y, sharp, np.ones((1, 1)), *args, 0.0, 0.0) == 0.0  # a delta: none


def test_confidence_intervals_are_student_t_over_the_seeds():
    rows = [
        {"status": "ok", "mode": "coded", "design": "p", "method": "hl", "x": 1.0, "y": v}
        for v in (20.0, 21.0, 23.0)
    ]
    ((xs, ys, ci),) = curves_ci(rows, "x", "y")[""].values()
    half = student.ppf(0.975, 2) * np.std([20, 21, 23], ddof=1) / math.sqrt(3)
    assert xs.tolist() == [1.0] and ys[0] == pytest.approx(64 / 3) and ci[0] == pytest.approx(half)
    ((_, _, one),) = curves_ci(rows[:1], "x", "y")[""].values()
    assert one[0] == 0.0


# --- a study that controls its error -----------------------------------------------------------
@pytest.mark.render
def test_every_point_meets_its_noise_target_and_states_the_error_budget(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    spec = load_study(str(path))
    estimates = []
    summary = run_study(
        spec, tmp_path / "out", workers=0, progress=False, on_estimate=estimates.append
    )
    assert summary.failed == 0 and estimates and summary.estimate_s > 0
    rows = _rows(tmp_path / "out")
    assert len(rows) == 4
    for r in rows:
        assert r["status"] == "ok"
        assert float(r["render_noise_ratio"]) <= 0.2 * 1.0001
        # by default the deconvolver is told the sensor's and the render's noise, no oracle
        parts = [float(r[k]) for k in ("noise_sigma", "render_noise_sigma")]
        assert float(r["deconv_sigma"]) == pytest.approx(math.sqrt(sum(p * p for p in parts)))
        assert r["model_error"] == "none"
        assert r["psnr_moving_no_model_sigma_db"] == r["psnr_moving_db"]
        kernel_mode = r["mode"] == "coded"
        assert (float(r["model_sigma"]) > 0) == kernel_mode
        assert (r["psnr_moving_exact_model_db"] != "") == kernel_mode
    # one render feeds both light levels: its target is the brighter one's (lower noise)
    coded = [r for r in rows if r["mode"] == "coded"]
    assert coded[0]["render_spp"] == coded[1]["render_spp"]
    ratios = sorted(float(r["render_noise_ratio"]) for r in coded)
    assert ratios[1] > 0.1 and ratios[0] < ratios[1] / 5
    report = (tmp_path / "out" / "report.md").read_text()
    assert "## Error budget" in report and "## What sets the high-light plateau" in report
    plateau = report.split("## What sets the high-light plateau")[1]
    assert "| exact model | oracle | model sigma | diffraction |" in plateau
    coded_row = next(line for line in plateau.splitlines() if line.startswith("| coded |"))
    assert coded_row.split("|")[-2].strip().startswith("out")  # geometric: left out, sized
    float(coded_row.split("|")[-4])  # the oracle's upper bound, beside the honest score
    assert all((r["psnr_moving_oracle_db"] != "") == (r["mode"] == "coded") for r in rows)
    assert not any((tmp_path / "out" / ".renders").glob("*/.partial"))


@pytest.mark.render
def test_a_study_over_its_budget_is_refused_after_its_pilots_which_are_kept(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY.replace('"short"]', '"short"]\nseed = [4]'))
    spec = load_study(str(path))
    with pytest.raises(ParameterError, match=r"over budget_hours = 1e-09 h"):
        run_study(spec, tmp_path / "out", workers=0, progress=False, budget_hours=1e-9)
    kept = list((tmp_path / "out" / ".renders").glob("*/.partial/state.json"))
    assert len(kept) == 2 and not _rows(tmp_path / "out")
    summary = run_study(spec, tmp_path / "out", workers=0, progress=False)
    assert summary.failed == 0 and len(_rows(tmp_path / "out")) == 4
