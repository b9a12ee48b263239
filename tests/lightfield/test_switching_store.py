"""A switching LCoS served by a light-field store (issue 58, item 2: the switching blend):
the store's synthesis against the plugin's direct render with the same switching time (pooled
chi^2), the cell basis's blend against the store's synthesis of a bitmap (exact), and the
blend's effect resolved (a capture that does not change with switching would pass the rest)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.plan import plan_capture
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.lightfield.synthesis import _resolve, pass_images
from pacam_render.optimize.cell_design import bitmap_design_spec, design_spec, disc_code
from tests.optimize.small_store import SPEC

SWITCH_MS = 2.0
"""Of a pattern's 2.81 ms (45 ms / 16): most of each window blends."""
BASE = replace(SPEC, crop=(440, 400, 64, 48), spp=32, passes=4, seed=5, cover_px_per_ms=1.4)


def _pooled(a, b) -> float:
    var = a.mc_sigma**2 + b.mc_sigma**2
    return float(((a.image - b.image) ** 2).sum() / var.sum())


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return render_lightfield(StoreSpec(BASE, alpha=1.0), tmp_path_factory.mktemp("sw") / "s",
                             progress=False)  # fmt: skip


@pytest.mark.render
def test_a_switching_capture_synthesised_is_its_direct_render(store):
    spec = replace(BASE, lcos_switching_ms=SWITCH_MS, seed=31, spp=64)
    syn = synthesize(store, spec, progress=False)
    direct = render_capture(spec, progress=False, truth=False)
    assert 0.8 <= _pooled(syn, direct) <= 1.25
    still = synthesize(store, replace(spec, lcos_switching_ms=None), progress=False)
    # the same samples: their difference is the blend's, 3 % of the light and more
    assert np.abs(syn.image - still.image).mean() > 0.03 * np.abs(still.image).mean()


def test_the_basis_blends_the_patterns_as_the_store_does(store, tmp_path):
    """The cell basis with switching composes a code as the store's per-sample transmission
    (:func:`~pacam_render.lightfield.codes.transmission`) blends the same code shown as a
    bitmap, exactly (the plugin does not switch bitmaps, so the bitmap's switching is set
    here on the store's own path); one pattern throughout blends to itself."""
    spec = replace(BASE, lcos_switching_ms=SWITCH_MS)
    code = disc_code(plan_capture(BASE), 8)[::-1].copy()  # reversed: each window differs
    basis = cell_basis(store, spec, cells=8)
    bitmap = bitmap_design_spec(BASE, basis, code, tmp_path / "d.toml")
    plan, params, design_plan = _resolve(store, design_spec(bitmap, tmp_path / "d.toml"))
    images, _ = pass_images(store, plan, {**params, "lcos_switching": SWITCH_MS}, design_plan)
    want = np.mean(images, axis=0)
    assert np.abs(basis.compose(code) - want).max() <= 1e-5 * np.abs(want).max()
    plain = cell_basis(store, BASE, cells=8)
    assert np.abs(plain.compose(code) - want).max() > 0.05 * np.abs(want).max()
    same = np.repeat(code[:1], len(code), axis=0)  # one pattern throughout: nothing blends
    assert np.allclose(basis.compose(same), plain.compose(same), rtol=1e-5, atol=1e-7)


def test_a_switching_time_longer_than_a_pattern_is_refused(store):
    with pytest.raises(ParameterError, match="lcos_switching_ms .* at most a pattern's time"):
        synthesize(store, replace(BASE, lcos_switching_ms=3.0), progress=False)
