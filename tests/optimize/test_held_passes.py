"""Choosing on samples the search never read (issue 58): a store's passes split into the
search's and the choice's. Synthesis and the cell basis from a subset of passes against the
whole store (linearity: the halves' mean is the whole), the default split, and the command's
report of it."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.plan import plan_capture
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code
from pacam_render.optimize.cell_run import BitmapProblem
from pacam_render.optimize.cell_select import split_passes
from tests.optimize.small_store import SPEC

FOUR = replace(SPEC, spp=8, passes=4, seed=9)


@pytest.fixture(scope="module")
def four(tmp_path_factory):
    return render_lightfield(StoreSpec(FOUR, alpha=1.0), tmp_path_factory.mktemp("lf") / "s4",
                             progress=False)  # fmt: skip


def test_the_halves_of_a_store_average_to_the_whole(four):
    whole = synthesize(four, FOUR, progress=False)
    a = synthesize(four, FOUR, progress=False, passes=(0, 1))
    b = synthesize(four, FOUR, progress=False, passes=(2, 3))
    assert np.allclose((a.image + b.image) / 2, whole.image, rtol=1e-5, atol=1e-7)
    assert not np.allclose(a.image, b.image)  # independent samples
    assert a.record.extra["lightfield"]["passes"] == [0, 1]
    assert np.all(np.isfinite(a.mc_sigma)) and a.mc_sigma.mean() > whole.mc_sigma.mean()
    with pytest.raises(ParameterError, match="passes: distinct store passes in 0..3"):
        synthesize(four, FOUR, progress=False, passes=(1, 1))


def test_a_basis_of_some_passes_composes_their_synthesis(four, tmp_path):
    plan = plan_capture(FOUR)
    code = disc_code(plan, 8)[::-1].copy()  # the schedule reversed: not the store's design
    basis = cell_basis(four, FOUR, cells=8, passes=(2, 3))
    spec = bitmap_design_spec(FOUR, basis, code, tmp_path / "d.toml")
    direct = synthesize(four, spec, progress=False, passes=(2, 3)).image
    assert np.abs(basis.compose(code) - direct).max() <= 1e-5 * np.abs(direct).max()


def test_the_default_split_holds_half_where_every_store_has_four_passes(four, store):
    p = BitmapProblem((str(four.folder),))
    assert split_passes(p, [four]) == ((0, 1), (2, 3))
    assert split_passes(p, [four, store]) == (None, None)  # a 2-pass store: no split
    assert split_passes(replace(p, held_passes=0), [four]) == (None, None)
    with pytest.raises(ParameterError, match="held_passes: 0, or 2 to"):
        split_passes(replace(p, held_passes=1), [four])


def test_the_command_chooses_on_the_held_passes(four, tmp_path, capsys):
    out = tmp_path / "opt"
    args = ["optimize", "--lightfield", str(four.folder), "--space", "discs", "--cells", "8",
            "--iterations", "2", "--starts", "1", "--noise-draws", "1", "--quiet",
            "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    assert "passes the search did not read (2, 3; it searched on 0, 1)" in capsys.readouterr().out
    doc = json.loads((out / "report.json").read_text())
    assert doc["passes"] == {"search": [0, 1], "choice": [2, 3]}
    assert len(doc["store_noise"]) == 1 and doc["store_noise"][0] > 0
    assert main([*args[:-2], "--held-passes", "1", "--out", str(tmp_path / "x")]) == 2
    assert "--held-passes: 0, or 2 to" in capsys.readouterr().err


def test_a_store_s_render_noise_against_the_sensor_s_falls_as_one_over_root_samples(four, store):
    """store_noise: the render noise over the sensor's of a store's capture. A store of 4x
    the samples (8 spp x 4 passes against 4 x 2, the same window) halves it (Monte Carlo);
    the report states it."""
    from pacam_render.optimize.rendered_run import base_spec, store_noise
    from pacam_render.sensor.model import SensorModel

    model = SensorModel.from_preset("grasshopper-icx285")
    r = [store_noise(synthesize(s, base_spec(s), progress=False), model, 300.0, "icx285")[0]
         for s in (store, four)]  # fmt: skip
    assert r[0] / r[1] == pytest.approx(2.0, rel=0.25)
    assert r[0] > 0.3  # a 4 spp store is noisier than a synthesised capture should be


def test_open_stores_share_one_cache_budget(four, store, monkeypatch):
    """Every open store's shard cache together stays under one budget (it was a quarter of the
    memory per store: eight stores pinned 22 of 23 GiB), and a dropped store gives its share
    back."""
    import gc

    from pacam_render.lightfield import Store
    from pacam_render.lightfield import store as store_module

    shared = {"budget": 0, "used": 0}
    monkeypatch.setattr(store_module, "_SHARED_CACHE", shared)
    a, b = Store.open(four.folder), Store.open(store.folder)
    one = sum(x.nbytes for x in next(a.shards(0))[0].values())
    shared["budget"] = int(2.5 * one)
    for s in (a, b):
        for p in range(s.manifest.passes):
            for _ in s.shards(p):
                pass
    assert 0 < shared["used"] <= shared["budget"] and a._cached + b._cached == shared["used"]
    held = a._cached
    del a
    gc.collect()
    assert shared["used"] == b._cached and held > 0
    del b  # inside the patch: its share goes back to this budget, not the session's
    gc.collect()
    assert shared["used"] == 0
