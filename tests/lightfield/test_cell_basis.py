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
from pacam_render.model.design_file import read_design, write_design
from pacam_render.model.masks import DISPLAY_SHAPE, MaskStack, pixel_centres_mm
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code, fine_disc_design_spec

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


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a, dtype=np.float64))))


def test_the_rasterisation_error_on_shared_samples_falls_with_the_grid(store, tmp_path):
    """Against the disc on the LCoS's own pixels synthesised from the same samples (so the
    difference is only the rim cells' samples, bench_cell_grid.py), finer cells come nearer;
    and that fine bitmap is the disc (far nearer it than the coarsest grid is)."""
    fine_spec = fine_disc_design_spec(SPEC, tmp_path / "fine.toml")
    fine = synthesize(store, fine_spec, progress=False).image
    disc = synthesize(store, SPEC, progress=False).image
    plan = plan_capture(SPEC)
    err = {g: _rms(cell_basis(store, SPEC, cells=g).compose(disc_code(plan, g)) - fine)
           for g in (8, 16, 32)}  # fmt: skip
    assert err[32] < err[16] < err[8], err
    assert _rms(fine - disc) < 0.5 * err[8], (_rms(fine - disc), err)


def test_a_native_bitmap_constant_on_the_cells_is_their_composition(store, tmp_path):
    """An independent path: a random code drawn as a full-display (1024 x 1280) bitmap by hand,
    each LCoS pixel inside the clear aperture showing its cell's value, read back from a design
    file, synthesised from the store, equals the basis's composition to rounding."""
    g = 8
    basis = cell_basis(store, SPEC, cells=g)
    rng = np.random.default_rng(4)
    code = rng.integers(0, 3, (basis.n_patterns, g, g)) / 2.0  # grey too; compresses well
    H, W = DISPLAY_SHAPE
    x, y = pixel_centres_mm(DISPLAY_SHAPE, basis.pitch_mm)  # camera frame: x falls with column
    R = basis.display_px * basis.pitch_mm / 2
    col = np.floor((-x + R) / (2 * R) * g).astype(int)  # the design frame's x = -x
    row = np.floor((-y + R) / (2 * R) * g).astype(int)
    inside = (x[None, :] ** 2 + y[:, None] ** 2 <= R * R) & (col[None] >= 0) & (col[None] < g)
    inside &= (row[:, None] >= 0) & (row[:, None] < g)
    masks = code[:, np.clip(row, 0, g - 1)[:, None], np.clip(col, 0, g - 1)[None, :]] * inside
    plan = plan_capture(SPEC)
    d = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px)
    cam = d.with_(pattern_centres_mm=None, quoted_a_i_px_per_ms2=None, name="by hand",
                  pattern_masks=MaskStack(masks.astype(np.float32), basis.pitch_mm))  # fmt: skip
    write_design(tmp_path / "hand.toml", cam, force=True)
    assert read_design(tmp_path / "hand.toml").pattern_masks.array.shape == (16, H, W)
    spec = dataclasses.replace(SPEC, design=str(tmp_path / "hand.toml"))
    direct = synthesize(store, spec, progress=False).image
    assert np.abs(basis.compose(code) - direct).max() <= 1e-5 * np.abs(direct).max()


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
