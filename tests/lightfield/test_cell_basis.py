"""The cell basis (issue 58, item 1): any code on the cells, composed from the basis, is the
store's own synthesis of the bitmap design file that shows it (an independent path: the design
file's masks read back, the plugin's transmission per sample), and the refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis, display_px, lens_cells
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code

SPEC = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(440, 400, 48, 32),
                             mode="coded", spp=2, passes=2, seed=5)  # fmt: skip


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lf") / "store"
    return render_lightfield(StoreSpec(SPEC, alpha=1.0), folder, progress=False)


@pytest.mark.parametrize("contrast", [None, 40.0])
def test_a_code_on_the_cells_is_the_stores_synthesis_of_its_design_file(store, tmp_path,
                                                                       contrast):  # fmt: skip
    spec = dataclasses.replace(SPEC, lcos_contrast=contrast)
    basis = cell_basis(store, spec, cells=8)
    rng = np.random.default_rng(1)
    code = rng.random((basis.n_patterns, 8, 8)) * (rng.random((basis.n_patterns, 8, 8)) < 0.4)
    design = bitmap_design_spec(spec, basis, code, tmp_path / "d.toml")
    direct = synthesize(store, design, progress=False).image
    got = basis.compose(code)
    assert np.abs(direct).max() > 0
    assert np.abs(got - direct).max() <= 1e-5 * np.abs(direct).max()


def test_the_prototypes_disc_rasterised_on_the_cells_nears_its_synthesis(store):
    """The disc rasterised on finer cells comes nearer the synthesised disc capture, and far
    nearer than the disc mirrored (the frame's check: its centres swing the other way)."""
    disc = synthesize(store, SPEC, progress=False).image
    err, mirrored = {}, {}
    for g in (8, 32):
        basis = cell_basis(store, SPEC, cells=g)
        code = disc_code(plan_capture(SPEC), g)
        err[g] = np.sqrt(np.mean((basis.compose(code) - disc) ** 2))
        mirrored[g] = np.sqrt(np.mean((basis.compose(code[:, :, ::-1]) - disc) ** 2))
    assert err[32] < err[8] < 0.5 * mirrored[8], (err, mirrored)


def test_every_reachable_cell_is_listed():
    ij = lens_cells(8, 1.0)
    assert len(ij) == 60  # an 8 x 8 grid over a unit disc: all but the 4 corners
    e = np.linspace(-1, 1, 9)
    for i in range(8):
        for j in range(8):
            xs, ys = np.linspace(e[j], e[j + 1], 41), np.linspace(e[i], e[i + 1], 41)
            hit = (xs[None] ** 2 + ys[:, None] ** 2 < 1).any()
            assert hit == any((ij == (i, j)).all(axis=1)), (i, j)


def test_bad_grids_and_codes_are_refused_before_any_work(store):
    with pytest.raises(ParameterError, match="cells"):
        display_px(6.97344, 0.01362, 48)
    with pytest.raises(ParameterError, match="no finer than the LCoS"):
        display_px(6.97344, 0.01362, 2048)
    with pytest.raises(ParameterError, match="max_bytes"):
        cell_basis(store, SPEC, cells=64, max_bytes=1000)
    basis = cell_basis(store, SPEC, cells=8)
    with pytest.raises(ParameterError, match=r"code: transmittances in \[0, 1\]"):
        basis.compose(np.full((basis.n_patterns, 8, 8), 1.5))
