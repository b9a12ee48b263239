"""The optimiser on rendered captures (issue 44, item 4): the centre basis against the store's
own synthesis of each design (exact on the grid), the scorer against the study's scoring, the
search's monotone path, and ``pacam optimize --lightfield`` end to end with its refusals."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.centre_basis import centre_basis
from pacam_render.model.design_file import read_design, write_design
from pacam_render.optimize.rendered import CaptureScorer, StoreObjective, coordinate_search
from pacam_render.optimize.rendered_run import candidate_positions, found_design
from pacam_render.restore.object_score import moving_shapes, psnr_moving_db, score
from tests.optimize.small_store import SPEC  # the store fixture: conftest.py


def _design_spec(spec, centres, path):
    """``spec`` with its design's centres moved, through a design file (the user's road)."""
    write_design(path, found_design(plan_capture(spec), centres), force=True)
    return dataclasses.replace(spec, design=str(path))


@pytest.mark.parametrize("contrast", [None, 40.0])
def test_a_design_on_the_grid_is_the_stores_own_synthesis(store, tmp_path, contrast):
    """compose() of any index equals synthesize() of that design's file: the same samples,
    weights and transmission (with an LCoS's leakage, 1/c of the whole lens)."""
    spec = dataclasses.replace(SPEC, lcos_contrast=contrast)
    positions = candidate_positions(plan_capture(spec).cam, 5)
    basis = centre_basis(store, spec, positions)
    rng = np.random.default_rng(0)
    for _ in range(2):
        index = rng.integers(0, len(positions), basis.n_patterns)
        direct = synthesize(store, _design_spec(spec, positions[index], tmp_path / "d.toml"),
                            progress=False)  # fmt: skip
        got = basis.compose(index)
        assert np.abs(got - direct.image).max() <= 1e-6 * np.abs(direct.image).max()
        assert np.abs(direct.image).max() > 0


def test_the_moving_psnr_is_the_study_scores(store):
    cap = synthesize(store, SPEC, progress=False)
    layers, objects = cap.extra_layers, cap.record.objects
    moving = moving_shapes(layers, objects)
    assert moving
    est = layers["sharp"] + np.random.default_rng(1).normal(0, 0.05, layers["sharp"].shape)
    want = score(est, layers, objects, moving, 4, 0)["psnr_moving_db"]
    assert psnr_moving_db(est, layers, objects, moving, 4) == pytest.approx(want, abs=1e-9)


def test_the_search_scores_a_candidate_as_its_own_capture_and_never_goes_down(store, tmp_path):
    """A candidate's score from the basis equals the scorer's on the design's synthesised
    capture (an independent path: design file, plan, transmission); the search's worst case
    only rises and ends at its final design's score."""
    plan = plan_capture(SPEC)
    positions = candidate_positions(plan.cam, 5)
    template = synthesize(store, SPEC, progress=False)
    scorer = CaptureScorer(template, "grasshopper-icx285", 300.0, (0, 1))
    obj = StoreObjective(centre_basis(store, SPEC, positions), template, scorer)
    index = np.random.default_rng(2).integers(0, len(positions), 16)
    direct = synthesize(store, _design_spec(SPEC, positions[index], tmp_path / "d.toml"),
                        progress=False)  # fmt: skip
    assert obj.psnr_db(index) == pytest.approx(scorer.psnr_db(direct), abs=1e-4)
    start = np.searchsorted(positions, plan.cam.pattern_centres_xy_mm()[:, 0])
    trace = coordinate_search([obj], start, 1, 0, progress=False)
    worst = [r[2] for r in trace.rows]
    assert all(b >= a for a, b in zip(worst, worst[1:]))
    assert trace.worst_db == pytest.approx(obj.psnr_db(trace.index), abs=1e-9)
    assert trace.evaluations == 1 + 16 * (len(positions) - 1)


def test_optimize_on_stores_from_the_command_line(store, tmp_path, capsys):
    out = tmp_path / "opt"
    args = ["optimize", "--lightfield", str(store.folder), "--positions", "3", "--sweeps", "1",
            "--noise-draws", "1", "--check-seeds", "2", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "Checked on fresh renders" in text and "worst case" in text
    doc = json.loads((out / "search.json").read_text())
    design = read_design(out / "design.toml")
    assert [c[0] for c in design.pattern_centres_mm] == pytest.approx(doc["found_centres_mm"])
    assert doc["found_worst_db"] >= doc["start_worst_db"]
    assert len(doc["fresh"]["stores"][0]["found_db"]) == 2
    assert (out / "search.png").stat().st_size > 0
    assert main(args) == 2  # no overwrite without --force
    assert "--force" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--max-velocity", "1"], "--max-velocity: a search on light-field stores"),
        (["--positions", "1"], "positions must be an integer >= 2"),
        (["--method", "nope"], "method must be one of"),
    ],
)
def test_optimize_on_stores_refuses_bad_input(store, tmp_path, capsys, extra, words):
    args = ["optimize", "--lightfield", str(store.folder), *extra, "--out", str(tmp_path / "o")]
    assert main(args) == 2
    assert words in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_stores_of_two_cameras_are_refused(store, tmp_path):
    from pacam_render.optimize.rendered_run import RenderedProblem, open_stores

    other = render_lightfield(StoreSpec(dataclasses.replace(SPEC, cover_px_per_ms=1.4), alpha=1.0),
                              tmp_path / "s2", progress=False)  # fmt: skip
    with pytest.raises(ParameterError, match="cover_px_per_ms.*share one camera"):
        open_stores(RenderedProblem((str(store.folder), str(other.folder))))
    with pytest.raises(ParameterError, match="no light-field store"):
        open_stores(RenderedProblem((str(tmp_path / "missing"),)))


def test_the_uniform_share_flag_is_checked(tmp_path, capsys):
    args = ["lightfield", "train", "--crop", "440,400,96,64", "--uniform-share", "0",
            "--out", str(tmp_path / "s")]  # fmt: skip
    assert main(args) == 2
    assert "--uniform-share" in capsys.readouterr().err
