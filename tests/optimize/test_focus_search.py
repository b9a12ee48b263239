"""Focus as a variable of the whole-aperture search (issue 58, "focus as a design variable"):
a store with a refocus margin serves the store's design refocused elsewhere, the cell basis
at that focus composes exactly what the store synthesises for the written design file there,
and ``pacam optimize --focus`` searches each focus, names its candidates by their focus and
writes the chosen one's focus."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.exposure.plan import plan_capture
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.model.design_file import read_design
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code
from pacam_render.optimize.cell_run import refocused_specs
from tests.optimize.small_store import SPEC

pytestmark = pytest.mark.render  # every test renders a small store

MARGIN_PX = 4
"""Refocus of the prototype's 751.6 mm camera to about 610-980 mm (shear k R_max <= 4 px)."""
FOCUS_MM = 900.0


@pytest.fixture(scope="module")
def margin_store(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lf_margin") / "store"
    return render_lightfield(StoreSpec(SPEC, alpha=1.0, margin_px=MARGIN_PX), folder,
                             progress=False)  # fmt: skip


def test_the_basis_at_another_focus_is_the_synthesis_of_its_design_file(margin_store, tmp_path):
    plan = plan_capture(SPEC)
    spec = refocused_specs([SPEC], plan, FOCUS_MM, tmp_path)[0]
    moved = plan_capture(spec)
    assert moved.cam.focus_distance_mm == pytest.approx(FOCUS_MM)
    np.testing.assert_allclose(moved.cam.pattern_centres_xy_mm(), plan.cam.pattern_centres_xy_mm())
    assert moved.cam.R_mm == pytest.approx(plan.cam.R_mm)
    basis = cell_basis(margin_store, spec, cells=8)
    rng = np.random.default_rng(2)
    code = np.maximum(disc_code(moved, 8), rng.random((16, 8, 8)) < 0.1).astype(float)
    cap = synthesize(margin_store, bitmap_design_spec(spec, basis, code, tmp_path / "d.toml"),
                     progress=False)  # fmt: skip
    assert read_design(tmp_path / "d.toml").focus_distance_mm == pytest.approx(FOCUS_MM)
    img = np.asarray(cap.image, float).reshape(basis.full.shape[1:])
    np.testing.assert_allclose(img, basis.compose(code), rtol=1e-4, atol=1e-6)
    own = cell_basis(margin_store, SPEC, cells=8).compose(code)
    assert np.abs(own - img).max() > 0.05 * np.abs(img).max()  # the focus moved the image


def test_a_focus_search_from_the_command_line(margin_store, tmp_path, capsys):
    out = tmp_path / "opt"
    args = ["optimize", "--lightfield", str(margin_store.folder), "--space", "bitmap",
            "--cells", "8", "--iterations", "2", "--starts", "1", "--noise-draws", "1",
            "--focus", f"{FOCUS_MM:g}", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "report.json").read_text())
    names = [r["design"] for r in doc["train"]]
    own = plan_capture(SPEC).cam.focus_distance_mm
    assert names == ["prototype", f"from prototype @ {own:.0f} mm", "from prototype @ 900 mm"]
    chosen = doc["choice"]["chosen"]
    focus = read_design(out / "design.toml").focus_distance_mm
    expect = own if chosen == "prototype" else float(re.search(r"@ (\d+) mm", chosen)[1])
    assert focus == pytest.approx(expect, abs=0.5) and doc["design_focus_mm"] == focus
    assert f"design.toml focuses at {focus:.0f} mm" in text
    assert len(doc["model_db"]["starts"]) == 2 and doc["evaluations"] == 2 * 2
