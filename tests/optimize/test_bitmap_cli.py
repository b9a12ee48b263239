"""``pacam optimize --lightfield STORE --space bitmap`` at a tiny size (issue 58, items 4 and
7): the design file it writes reads back with no warning and keeps the prototype's light, its
report's prototype row is the rendered objective's own score, and bad flags get one line and
exit 2 before any folder is made."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.lightfield import synthesize
from pacam_render.limits import PacamWarning
from pacam_render.model.design_file import read_design
from pacam_render.optimize.rendered import CaptureScorer
from pacam_render.optimize.rendered_run import base_spec


def test_a_bitmap_search_from_the_command_line(store, tmp_path, capsys):
    out = tmp_path / "opt"
    args = ["optimize", "--lightfield", str(store.folder), "--space", "bitmap", "--cells", "8",
            "--iterations", "3", "--starts", "2", "--noise-draws", "1", "--quiet",
            "--objective", "moving+still", "--still-weight", "0.5", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "Scored with the real pipeline" in text
    assert "(moving PSNR + 0.5 still PSNR) / 1.5" in text
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)  # written, so not "edited after"
        cam = read_design(out / "design.toml")
    masks = cam.pattern_masks.array
    assert cam.n_patterns == 16 and set(np.unique(masks)) <= {0.0, 1.0}
    doc = json.loads((out / "report.json").read_text())
    light = doc["light_model"]
    assert light["found"] == pytest.approx(light["prototype_capture"], rel=2e-3)  # fixed light
    rows = doc["train"]
    assert [r["design"] for r in rows] == ["prototype", "from prototype", "from random 1"]
    proto = rows[0]
    for found in rows[1:]:
        assert found["light_rel"] == pytest.approx(1.0, abs=2e-3)  # the captures' light factors
        assert found["range_px_per_ms"] is None  # a bitmap: no fitted parabola
    # the choice is the best of the real pipeline's (moving + 0.5 still) / 1.5, computed here
    value = {r["design"]: (r["psnr_moving_db"] + 0.5 * r["psnr_static_db"]) / 1.5 for r in rows}
    chosen = doc["choice"]["chosen"]
    assert chosen == max(value, key=lambda k: (value[k], k == "prototype")), value
    assert chosen != "prototype"  # this seed's search beats it (else design.toml is a disc)
    template = synthesize(store, base_spec(store), progress=False)
    own = CaptureScorer(template, "grasshopper-icx285", 300.0, (0,)).psnr_db(template)
    assert proto["psnr_moving_db"] == pytest.approx(own, abs=1e-6)
    assert (out / "report.png").stat().st_size > 0 and (out / "design.masks.npz").exists()


def test_grey_levels_from_the_command_line(store, tmp_path):
    """--levels 4: the design file's masks carry the grey steps 0, 1/3, 2/3, 1 (an LCoS that
    shows grey), read back as written; the default stays binary (the test above)."""
    out = tmp_path / "grey"
    args = ["optimize", "--lightfield", str(store.folder), "--space", "bitmap", "--cells", "8",
            "--levels", "4", "--light", "free", "--iterations", "60", "--starts", "1",
            "--noise-draws", "1", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    masks = read_design(out / "design.toml").pattern_masks.array
    steps = np.unique(masks)
    assert np.isclose(steps[:, None], np.arange(4) / 3, atol=1e-6).any(axis=1).all(), steps
    assert ((steps > 0.1) & (steps < 0.9)).any(), steps  # grey, not only binary
    assert json.loads((out / "report.json").read_text())["problem"]["levels"] == 4


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--space", "grid"], "--space: one of centres, bitmap"),
        (["--space", "bitmap", "--cells", "48"], "--cells: a grid of G x G cells"),
        (["--space", "bitmap", "--light", "more"], "--light: one of free, fixed"),
        (["--space", "bitmap", "--iterations", "0"], "--iterations must be an integer >= 1"),
        (["--space", "bitmap", "--positions", "5"], "--positions: only a search with --space"),
        (["--cells", "16"], "--cells: only a search with --space bitmap"),
        (["--space", "bitmap", "--levels", "1"], "--levels must be an integer 2..256, got 1"),
        (["--space", "bitmap", "--levels", "257"], "--levels must be an integer 2..256"),
        (["--levels", "4"], "--levels: only a search with --space bitmap"),
        (["--space", "bitmap", "--objective", "all"], "--objective: one of moving, moving+still"),
        (["--space", "bitmap", "--still-weight", "2"], "--still-weight: only --objective"),
        (
            ["--space", "bitmap", "--objective", "moving+still", "--still-weight", "-1"],
            "--still-weight: a finite number > 0",
        ),
        (["--objective", "moving"], "--objective: only a search with --space bitmap"),
        (["--space", "bitmap", "--aggregate", "max"], "--aggregate: one of mean, worst, got"),
        (["--aggregate", "worst"], "--aggregate: only a search with --space bitmap"),
        (["--space", "bitmap", "--focus", "100000"], "px of refocus from the store"),
        (["--space", "bitmap", "--focus", "-5"], "--focus must be > 0 mm, got -5"),
        (["--space", "bitmap", "--focus", "900", "900"], "--focus: each focus once"),
        (["--focus", "900"], "--focus: only a search with --space bitmap"),
    ],
)
def test_bad_bitmap_flags_are_one_line_before_any_work(store, tmp_path, capsys, extra, words):
    args = ["optimize", "--lightfield", str(store.folder), *extra, "--out", str(tmp_path / "o")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()
