"""The planner's cost model (issue 46, item 6): its counts against what the renders did, its fit
against known rates, its history file, the bar over stages, and the estimates the commands say
before they start."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.exposure import render_time as cost
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec

TINY = {"scene": "train", "width": 48, "height": 36, "spp": 16, "seed": 2}


@pytest.fixture
def history(tmp_path, monkeypatch):
    path = tmp_path / "times.jsonl"
    monkeypatch.setenv("PACAM_RENDER_TIMES", str(path))
    return path


def _rows(path) -> list[dict]:
    return [json.loads(x) for x in path.read_text().splitlines()]


@pytest.mark.render
@pytest.mark.parametrize("mode", ["coded", "reference"])
def test_the_planned_work_is_what_the_render_did(history, mode):
    """The estimate's samples and renders, counted from the plan alone, equal the ones the
    render counted step by step, and the record's spp x pixels (moving coded: 16 patterns'
    steps; the reference: one static render per pass, its own sharp layer)."""
    spec = CaptureSpec.geometric(mode=mode, **TINY)
    est = cost.estimate_capture(spec, first=False)
    cap = render_capture(spec, progress=False, truth=True)
    (row,) = _rows(history)
    planned = sum(est.parts.values(), cost.Work())
    assert row["renders"] == planned.renders
    assert row["msamples"] == pytest.approx(planned.msamples, rel=1e-9)
    assert est.parts["capture"].msamples * 1e6 == 48 * 36 * cap.record.effective_spp
    assert ("truth" in est.parts) == (mode != "reference")
    if mode == "coded":
        assert est.parts["capture"].renders == 2 * cap.record.n_steps > 2


@pytest.mark.render
def test_auto_diffraction_preview_is_its_own_planned_call(history):
    spec = CaptureSpec(mode="coded", diffraction="auto", relative_illumination="off", **TINY)
    est = cost.estimate_capture(spec, truth=False, first=False)
    render_capture(spec, progress=False, truth=False)
    preview, capture = _rows(history)
    for row, part in ((preview, est.parts["preview"]), (capture, est.parts["capture"])):
        assert (row["renders"], row["calls"]) == (part.renders, part.calls)
        assert row["msamples"] == pytest.approx(part.msamples, rel=1e-9)


def test_the_fit_recovers_known_rates():
    """Rows made from known rates (closed form) give them back; counts that move together
    (every call a process's first) leave the rate to one of them, with the same prediction."""
    true = np.array([0.2, 1.1, 0.05, 0.03])
    rng = np.random.default_rng(0)
    rows = []
    for i in range(12):
        w = cost.Work(1, int(i % 3 == 0), float(rng.uniform(0.1, 40)), int(rng.integers(2, 300)))
        rows.append({**vars(w), "seconds": float(true @ w.vector())})
    assert np.allclose(cost.fit_rates(rows), true, rtol=1e-8)
    firsts = [{**r, "first_calls": 1, "seconds": r["seconds"] + 1.1 * (1 - r["first_calls"])}
              for r in rows]  # fmt: skip
    fitted = np.array(cost.fit_rates(firsts))
    a = np.array([[r[k] for k in cost.FIELDS] for r in firsts])
    assert np.allclose(a @ fitted, [r["seconds"] for r in firsts], rtol=1e-8)
    assert cost.fit_rates(rows[: cost.MIN_HISTORY - 1]) is None


def test_rates_come_from_the_history_once_there_is_enough(history):
    assert cost.rates("llvm_ad_rgb").per == cost.REFERENCE_RATES["capture"]
    assert cost.rates("psf llvm_ad_rgb").per == cost.REFERENCE_RATES["psf"]
    assert "reference machine" in cost.rates("llvm_ad_rgb").basis
    true = np.array([0.1, 0.5, 0.02, 0.01])
    for i in range(cost.MIN_HISTORY + 2):
        w = cost.Work(1, int(i == 0), 3.0 * (i + 1), 10 * (i % 3 + 1))
        cost.remember("llvm_ad_rgb", w, float(true @ w.vector()))
    bad = [
        '{"key": "llvm_ad_rgb", "seco',
        '{"key": "llvm_ad_rgb", "calls": 1, "first_calls": 0, '
        '"msamples": Infinity, "renders": 1, "seconds": 2}',
    ]  # a cut line, a hand edit
    history.write_text(history.read_text() + "\n".join(bad) + "\n")
    r = cost.rates("llvm_ad_rgb")
    assert np.allclose(r.per, true, rtol=1e-6)
    assert r.basis == f"{cost.MIN_HISTORY + 2} earlier llvm_ad_rgb renders on this machine"
    assert "reference machine" in cost.rates("scalar_rgb").basis  # another variant's own


def test_the_history_is_trimmed_by_rename(history, monkeypatch):
    monkeypatch.setattr(cost, "HISTORY_KEPT", 5)
    for i in range(60):
        cost.remember("k", cost.Work(1, 0, 1.0, 1), 1.0 + i)
    rows = _rows(history)
    assert len(rows) <= 2 * 5 + 60 and rows[-1]["seconds"] == 60.0
    assert len(rows) < 60  # trimmed at least once
    assert not list(history.parent.glob(".*.tmp"))


def test_an_unwritable_history_costs_only_accuracy(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("PACAM_RENDER_TIMES", str(blocker / "times.jsonl"))  # under a file
    cost.remember("k", cost.Work(1, 0, 1.0, 1), 1.0)  # no exception
    assert "reference machine" in cost.rates("llvm_ad_rgb").basis


def test_the_overall_bar_ends_each_stage_at_its_share():
    """Steps move the bar by their predicted seconds, never past the stage's share; a stage
    that ran short is completed at its end; the last ends at the total."""
    rates = cost.Rates((0.0, 0.0, 1.0, 0.0), "test")
    with cost.Overall({"a": 2.0, "b": 3.0}, rates, "t", progress=False) as bar:
        with bar.stage("a"):
            assert cost.in_overall()
            cost.count_step(5.0)  # predicted 5 s, the stage has 2
            assert bar.n == 2.0
        with bar.stage("b"):
            cost.count_step(1.0)
            assert bar.n == 3.0
        assert bar.n == 5.0 == bar.total
    assert not cost.in_overall()


@pytest.mark.render
def test_render_says_its_estimate_before_any_render(tmp_path, capsys):
    argv = ["render", "train", "--width", "48", "--height", "36", "--spp", "16",
            "--out", str(tmp_path / "c")]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert err.index("estimate: about") < err.index("diffraction auto: rendering a short")
    assert "preview" in err and "capture" in err and "truth" in err
    assert main([*argv[:-1], str(tmp_path / "q"), "--quiet"]) == 0
    assert "estimate:" not in capsys.readouterr().err


@pytest.mark.render
def test_the_psf_work_is_what_the_psf_render_did(history):
    from pacam_render.model.camera import prototype
    from pacam_render.psf_render.render import psf_history_key, psf_work, render_psf
    from pacam_render.psf_render.spec import PSFSpec

    spec = PSFSpec("coded", 0.3, size=41, spp=8)
    work = psf_work(prototype(), spec)
    k = render_psf(prototype(), "coded", 0.3, size=41, spp=8)
    (row,) = _rows(history)
    assert row["key"] == psf_history_key()
    assert (row["renders"], work.renders) == (k.passes, k.passes)
    assert row["msamples"] * 1e6 == pytest.approx(k.particles) == work.msamples * 1e6


def test_optimize_says_its_longest_time_first(tmp_path, capsys):
    argv = ["optimize", "--max-velocity", "1.4", "--quick", "--starts", "1", "--iterations", "3",
            "--out", str(tmp_path / "o")]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "estimate: optimise at most" in err and "3 iterations of about 1.2" in err
