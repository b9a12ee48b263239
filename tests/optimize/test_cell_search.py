"""The cell objective and its gradient search (issue 58, items 2-3): the hand-written adjoint
against central finite differences on a random grey code, a search that climbs from its
starts, and a found code written as a design file that the store synthesises as the basis
composes it."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.model.design_file import read_design
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code
from pacam_render.optimize.cell_objective import cell_problem, objective, parts
from pacam_render.optimize.cell_search import gradient_search, project

pytestmark = pytest.mark.render  # every test renders a small store

SPEC = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(440, 400, 48, 32),
                             mode="coded", spp=4, passes=2, seed=7)  # fmt: skip
G = 8


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lf") / "store"
    store = render_lightfield(StoreSpec(SPEC, alpha=1.0), folder, progress=False)
    plan = plan_capture(SPEC)
    basis = cell_basis(store, SPEC, cells=G)
    base = disc_code(plan, G)
    template = synthesize(store, SPEC, progress=False)
    # still_edge_px 3: the scorer's 32 columns would leave none of this 48 px window
    problem = cell_problem(basis, template, plan, base, "grasshopper-icx285", 300.0, np.float64,
                           still_edge_px=3)  # fmt: skip
    return store, basis, base, problem


def test_the_gradient_is_central_finite_differences_on_a_random_grey_code(setup):
    _, basis, _, problem = setup
    rng = np.random.default_rng(3)
    code = rng.uniform(0.05, 0.95, (basis.n_patterns, G, G))
    value, grad = objective(problem, code)
    assert np.isfinite(value) and grad.shape == code.shape
    h = 1e-5
    for _ in range(6):  # single cells, then random directions
        k, (i, j) = (
            rng.integers(basis.n_patterns),
            basis.cells_ij[rng.integers(len(basis.cells_ij))],
        )
        d = np.zeros_like(code)
        d[k, i, j] = 1.0
        fd = (
            objective(problem, code + h * d, False)[0] - objective(problem, code - h * d, False)[0]
        ) / (2 * h)
        assert abs(grad[k, i, j] - fd) <= 1e-3 * abs(fd) + 1e-9, (k, i, j, grad[k, i, j], fd)
    d = rng.normal(size=code.shape) * 0.1
    fd = (
        objective(problem, code + h * d, False)[0] - objective(problem, code - h * d, False)[0]
    ) / (2 * h)
    assert abs(np.sum(grad * d) - fd) <= 1e-3 * abs(fd)
    off_lens = np.ones((G, G), bool)
    off_lens[basis.cells_ij[:, 0], basis.cells_ij[:, 1]] = False
    assert np.all(grad[:, off_lens] == 0)  # a cell no lens point reaches changes nothing


def test_the_search_climbs_and_its_design_file_is_the_basis_composition(setup, tmp_path):
    store, basis, base, problem = setup
    start_db = objective(problem, base, False)[0]
    found = gradient_search([problem], {"prototype": base}, iterations=8, step=0.2)
    assert found.rows[-1][2] > found.rows[0][2]  # the relaxed objective rose
    assert np.isin(found.code, (0.0, 1.0)).all()
    assert found.projected_db == pytest.approx(objective(problem, found.code, False)[0])
    assert np.isfinite(start_db)
    spec = bitmap_design_spec(SPEC, basis, found.code, tmp_path / "found.toml")
    cam = read_design(tmp_path / "found.toml")
    assert cam.pattern_masks is not None and cam.pattern_masks.n_patterns == basis.n_patterns
    direct = synthesize(store, spec, progress=False).image
    assert np.abs(basis.compose(found.code) - direct).max() <= 1e-5 * np.abs(direct).max()


def test_bad_search_input_is_refused(setup):
    _, basis, base, problem = setup
    with pytest.raises(ParameterError, match="iterations"):
        gradient_search([problem], {"prototype": base}, iterations=0)
    with pytest.raises(ParameterError, match="levels"):
        project(base, 1)
    with pytest.raises(ParameterError, match="all-black"):
        objective(problem, np.zeros_like(base))


def test_the_still_term_and_its_gradient_are_central_finite_differences(setup):
    _, basis, _, problem = setup
    assert problem.still.any() and problem.mask.any()
    rng = np.random.default_rng(5)
    code = rng.uniform(0.05, 0.95, (basis.n_patterns, G, G))
    w = 0.7
    value, grad = objective(problem, code, True, w)
    moving, still = parts([problem], code)
    assert value == pytest.approx((moving + w * still) / (1 + w))
    assert moving == pytest.approx(objective(problem, code, False)[0])
    h = 1e-5
    for _ in range(3):
        d = rng.normal(size=code.shape) * 0.1
        fd = (objective(problem, code + h * d, False, w)[0]
              - objective(problem, code - h * d, False, w)[0]) / (2 * h)  # fmt: skip
        assert abs(np.sum(grad * d) - fd) <= 1e-3 * abs(fd), (np.sum(grad * d), fd)


def test_the_still_psnr_is_the_closed_form_of_a_flat_residual(setup):
    """An independent check of E_s: with sharp replaced so that the restored image minus
    sharp is a known constant c on the still pixels, the noise-free part is c^2 |N|."""
    _, basis, base, problem = setup
    from dataclasses import replace as dc_replace

    from pacam_render.optimize.cell_objective import _forward, _weights

    f = _forward(problem, _weights(problem, base), 1.0)
    restored = f["r_s"] + problem.sharp * problem.still[..., None]
    shifted = dc_replace(problem, sharp=np.where(problem.still[..., None], restored - 0.1,
                                                 problem.sharp))  # fmt: skip
    g = _forward(shifted, _weights(problem, base), 1.0)
    n_s = int(problem.still.sum()) * problem.sharp.shape[2]
    noise = n_s * f["s2"] * f["w2"]
    assert g["E_s"] == pytest.approx(0.01 * n_s + noise, rel=1e-9)


def test_a_bad_still_weight_is_refused(setup):
    _, _, base, problem = setup
    with pytest.raises(ParameterError, match="still_weight"):
        gradient_search([problem], {"prototype": base}, iterations=1, still_weight=-1.0)
    with pytest.raises(ParameterError, match="still_weight"):
        gradient_search([problem], {"prototype": base}, iterations=1, still_weight=float("nan"))


def test_a_store_with_no_still_pixel_scores_its_moving_objects_only(setup):
    """With a still weight, a window whose scored columns hold no still pixel counts its
    moving PSNR alone in the mean; with no such pixel in any store the weight is refused."""
    from dataclasses import replace as dc_replace

    from pacam_render.optimize.cell_objective import pooled_objective

    _, _, base, problem = setup
    bare = dc_replace(problem, still=np.zeros_like(problem.still))
    w = 0.5
    moving, still = parts([problem], base)
    bare_moving = objective(bare, base, False)[0]
    got = pooled_objective([problem, bare], base, False, w)[0]
    assert got == pytest.approx(((moving + w * still) / (1 + w) + bare_moving) / 2)
    assert parts([problem, bare], base)[1] == pytest.approx(still)  # the still stores' mean
    with pytest.raises(ParameterError, match="no store's window shows a still pixel"):
        gradient_search([bare], {"prototype": base}, iterations=1, still_weight=w)


def test_several_codes_at_once_are_each_code_alone(setup):
    """objectives() reads the basis once for S codes: each value and gradient is that code's
    own (objective(), checked above against finite differences)."""
    from pacam_render.optimize.cell_objective import objectives

    _, basis, _, problem = setup
    rng = np.random.default_rng(11)
    codes = rng.uniform(0.05, 0.95, (3, basis.n_patterns, G, G))
    vals, grads = objectives(problem, codes, True, 0.5)
    for code, v, g in zip(codes, vals, grads):
        v1, g1 = objective(problem, code, True, 0.5)
        assert v == pytest.approx(v1, rel=1e-12) and np.allclose(g, g1, rtol=1e-9, atol=1e-12)


def test_the_worst_aggregate_is_the_soft_minimum_of_the_gains_and_its_gradient_fd(setup):
    """The "worst" aggregate (:func:`pooled_objectives`): equal to the mean where every store
    gains alike (the same store twice), between mean_b + min gain and the mean otherwise, and
    its gradient central finite differences on a random grey code over two different stores
    (the second's truth dimmed, so its gains differ)."""
    import dataclasses

    from pacam_render.optimize.cell_objective import WORST_SOFTNESS_DB, pooled_objective

    _, basis, _, problem = setup
    other = dataclasses.replace(problem, sharp=problem.sharp * 0.8, base_db={})
    rng = np.random.default_rng(5)
    code = rng.uniform(0.05, 0.95, (basis.n_patterns, G, G))
    same = [problem, dataclasses.replace(problem, base_db={})]
    assert pooled_objective(same, code, False, aggregate="worst")[0] == pytest.approx(
        objective(problem, code, False)[0], abs=1e-9)  # fmt: skip
    pair = [problem, other]
    v, g = pooled_objective(pair, code, aggregate="worst")
    vals = np.array([objective(q, code, False)[0] for q in pair])
    b = np.array([objective(q, q.base_code, False)[0] for q in pair])
    assert b.mean() + (vals - b).min() - 1e-9 <= v <= vals.mean() + 1e-9
    tau = WORST_SOFTNESS_DB
    assert v == pytest.approx(b.mean() - tau * np.log(np.mean(np.exp(-(vals - b) / tau))))
    h = 1e-5
    for _ in range(3):
        d = rng.normal(size=code.shape) * 0.1
        up = pooled_objective(pair, code + h * d, False, aggregate="worst")[0]
        down = pooled_objective(pair, code - h * d, False, aggregate="worst")[0]
        fd = (up - down) / (2 * h)
        assert abs(np.sum(g * d) - fd) <= 1e-3 * abs(fd) + 1e-9, (np.sum(g * d), fd)
    with pytest.raises(ParameterError, match="aggregate`: one of mean, worst"):
        gradient_search(pair, {"x": code}, iterations=1, aggregate="max")
