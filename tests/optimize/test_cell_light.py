"""Fixed total light in the cell-code search (issue 58, item 2): the projection onto the codes
of a given light is the Euclidean one (against a general QP solver), the binary code keeps the
light within one cell's, and a search at fixed light keeps its light while it climbs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import minimize

from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.optimize.cell_design import disc_code
from pacam_render.optimize.cell_objective import cell_problem
from pacam_render.optimize.cell_search import (
    gradient_search,
    light_of,
    project_levels,
    project_light,
)


def _toy(seed=0, n=2, G=3):
    """A problem's light terms only: random lambda on every cell of an n x G x G grid."""
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((G, G), bool))
    return SimpleNamespace(cells_ij=ij, lam=rng.uniform(0.2, 1.0, (n, len(ij))))


def _qp(a, lam, target):
    """min ||x - a||^2 subject to 0 <= x <= 1 and lam . x = target, by SLSQP."""
    return minimize(lambda x: np.sum((x - a) ** 2), np.full(a.size, 0.5),
                    jac=lambda x: 2 * (x - a), bounds=[(0, 1)] * a.size, method="SLSQP",
                    constraints={"type": "eq", "fun": lambda x: x @ lam - target},
                    options={"ftol": 1e-14, "maxiter": 500})  # fmt: skip


def test_the_light_projection_is_the_euclidean_one():
    p = _toy()
    rng = np.random.default_rng(1)
    for target in (1.0, 3.0, 6.0):
        a = rng.uniform(-0.5, 1.5, (2, 3, 3))
        got = project_light(a, p, target)
        ref = _qp(a.ravel(), p.lam.ravel(), target)
        assert ref.success
        assert np.abs(got.ravel() - ref.x).max() < 1e-5
        assert light_of(p, got) == pytest.approx(target, rel=1e-12)
        assert got.min() >= 0 and got.max() <= 1


def test_the_binary_code_keeps_the_light_within_half_a_cell():
    p = _toy(2, n=4, G=6)
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 1, (4, 6, 6))
    for target in (2.0, 10.0, 25.0):
        b = project_levels(project_light(a, p, target), p, target, 2)
        assert set(np.unique(b)) <= {0.0, 1.0}
        assert abs(light_of(p, b) - target) <= 0.5 * p.lam.max() + 1e-12
        relaxed = project_light(a, p, target)
        assert relaxed[b == 1].min() >= relaxed[b == 0].max() - 1e-12  # the highest opened
    with pytest.raises(ParameterError, match="light: a target"):
        project_light(a, p, 1e6)


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    spec = CaptureSpec.geometric(scene="train", width=1280, height=960,
                                 crop=(440, 400, 48, 32), mode="coded", spp=4, passes=2,
                                 seed=7)  # fmt: skip
    store = render_lightfield(StoreSpec(spec, alpha=1.0), tmp_path_factory.mktemp("lf") / "s",
                              progress=False)  # fmt: skip
    basis = cell_basis(store, spec, cells=8)
    base = disc_code(plan_capture(spec), 8)
    template = synthesize(store, spec, progress=False)
    return cell_problem(
        basis, template, plan_capture(spec), base, "grasshopper-icx285", 300.0
    ), base


def test_a_fixed_light_search_keeps_the_prototypes_light_and_climbs(problem):
    p, base = problem
    rng = np.random.default_rng(5)
    starts = {"prototype": base, "random": (rng.random(base.shape) < 0.5).astype(float)}
    found = gradient_search([p], starts, iterations=10, light="fixed", reference=base)
    assert set(np.unique(found.code)) <= {0.0, 1.0}
    assert abs(light_of(p, found.code) - light_of(p, base)) <= 0.5 * p.lam.max()
    assert found.rows[9][2] > found.rows[0][2]  # the prototype's start climbed
    with pytest.raises(ParameterError, match="reference"):
        gradient_search([p], starts, iterations=1, light="fixed")
    with pytest.raises(ParameterError, match="light: one of free, fixed"):
        gradient_search([p], starts, iterations=1, light="some")
