"""Issue 58's "Exact": a found design, synthesised from a store, is a direct ``pacam render
--design`` of the design file the search wrote, within their Monte Carlo sigmas (pooled chi^2
in [0.8, 1.25]): a bitmap and a discs design, each on its training scene and on a scene the
search never saw (a family scene's store)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.model.design_file import write_design
from pacam_render.optimize.cell_design import bitmap_design, design_spec, disc_code
from pacam_render.optimize.cell_objective import cell_problem
from pacam_render.optimize.cell_search import gradient_search
from pacam_render.optimize.disc_space import DiscGrid, disc_design, disc_search, plan_discs

G = 8
TRAIN = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(440, 400, 64, 48),
                              mode="coded", spp=16, passes=4, seed=3)  # fmt: skip
HIDDEN = replace(TRAIN, scene="family:occluders:3", crop=(560, 420, 64, 48))


def _pooled(a, b) -> float:
    """sum (a - b)^2 / sum (sigma_a^2 + sigma_b^2): 1 for two unbiased estimates."""
    var = a.mc_sigma**2 + b.mc_sigma**2
    return float(((a.image - b.image) ** 2).sum() / var.sum())


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    """A short bitmap and discs search on the train store, each written as a design file."""
    root = tmp_path_factory.mktemp("found")
    store = render_lightfield(StoreSpec(TRAIN, alpha=1.0), root / "train", progress=False)
    plan = plan_capture(TRAIN)
    template = synthesize(store, TRAIN, progress=False)
    basis = cell_basis(store, TRAIN, cells=G)
    problem = cell_problem(basis, template, plan, disc_code(plan, G), "grasshopper-icx285",
                           300.0, still_edge_px=3)  # fmt: skip
    bitmap = gradient_search([problem], {"prototype": disc_code(plan, G)}, iterations=4,
                             light="fixed", reference=template.record.light_factor)  # fmt: skip
    write_design(root / "bitmap.toml", bitmap_design(plan, basis, bitmap.code), force=True)
    cam = plan.cam
    discs = disc_search([problem], {"prototype": plan_discs(plan)},
                        DiscGrid(G, cam.R_max_mm, cam.lcos_pitch_mm), iterations=4)  # fmt: skip
    write_design(root / "discs.toml", disc_design(plan, discs.discs), force=True)
    hidden = render_lightfield(StoreSpec(HIDDEN, alpha=1.0), root / "hidden", progress=False)
    return {"train": store, "hidden": hidden}, root


@pytest.mark.render
@pytest.mark.parametrize("which", ["bitmap", "discs"])
@pytest.mark.parametrize("scene", ["train", "hidden"])
def test_a_found_design_synthesised_is_its_direct_render(found, which, scene):
    stores, root = found
    base = TRAIN if scene == "train" else HIDDEN
    spec = design_spec(replace(base, seed=41), root / f"{which}.toml")
    syn = synthesize(stores[scene], spec, progress=False)
    direct = render_capture(spec, progress=False, truth=False)
    assert syn.record.light_factor == pytest.approx(direct.record.light_factor, rel=1e-6)
    assert 0.8 <= _pooled(syn, direct) <= 1.25
    assert not np.allclose(syn.image, synthesize(stores[scene], base, progress=False).image)
