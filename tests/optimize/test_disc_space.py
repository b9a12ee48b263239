"""The discs design space (issue 58, item 2): one disc per pattern window moving in x and y,
one radius, searched by gradient on the cells' basis. The chain rule through the soft
rasterisation against central finite differences; the soft code's area against pi R^2 and its
half-level set against the design file's own rasterisation (:func:`disc_code` of the written
design, read back); every disc kept inside the lens; a search that climbs; and the command's
design file, patterns picture and held-out report."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.exposure.plan import plan_capture
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import cell_basis
from pacam_render.model.design_file import read_design, write_design
from pacam_render.optimize.cell_design import design_spec, disc_code
from pacam_render.optimize.cell_objective import cell_problem
from pacam_render.optimize.disc_space import (
    DiscGrid,
    Discs,
    disc_design,
    disc_objective,
    disc_search,
    plan_discs,
    project_inside,
    soft_code,
)
from tests.optimize.small_store import SPEC

G = 8


@pytest.fixture(scope="module")
def setup(store):
    plan = plan_capture(SPEC)
    basis = cell_basis(store, SPEC, cells=G)
    template = synthesize(store, SPEC, progress=False)
    problem = cell_problem(basis, template, plan, disc_code(plan, G), "grasshopper-icx285",
                           300.0, np.float64, still_edge_px=3)  # fmt: skip
    cam = plan.cam
    return plan, problem, DiscGrid(G, cam.R_max_mm, cam.lcos_pitch_mm)


def _moved(plan, grid) -> Discs:
    """The prototype's discs moved off the x axis (y != 0), still inside the lens."""
    d = plan_discs(plan)
    rng = np.random.default_rng(5)
    c = d.centres_mm + rng.normal(0, 0.8, d.centres_mm.shape)
    return project_inside(Discs(c, d.R_mm * 1.1, d.is_open), grid, True)


def test_the_chain_rule_is_central_finite_differences(setup):
    plan, problem, grid = setup
    d = _moved(plan, grid)
    _, (gc, gR) = disc_objective([problem], d, grid, True, 0.0)
    h = 1e-6
    rng = np.random.default_rng(1)
    for _ in range(3):
        dc = rng.normal(size=d.centres_mm.shape) * d.is_open[:, None]
        dR = float(rng.normal())
        hi = disc_objective([problem], Discs(d.centres_mm + h * dc, d.R_mm + h * dR, d.is_open),
                            grid, False)[0]  # fmt: skip
        lo = disc_objective([problem], Discs(d.centres_mm - h * dc, d.R_mm - h * dR, d.is_open),
                            grid, False)[0]  # fmt: skip
        fd = (hi - lo) / (2 * h)
        assert np.sum(gc * dc) + gR * dR == pytest.approx(fd, rel=1e-3, abs=1e-7)


def test_the_soft_code_is_the_disc_the_design_file_rasterises(setup, tmp_path):
    """Its area is pi R^2 (to the edge's linear ramp), and its half-level set is the disc the
    written design, read back, rasterises on the cells: one frame (x right, y down)."""
    plan, _, _ = setup
    cam = plan.cam
    grid = DiscGrid(32, cam.R_max_mm, cam.lcos_pitch_mm)
    d = _moved(plan, grid)
    code, _ = soft_code(d, grid)
    area = code.sum(axis=(1, 2)) * grid.pitch_mm**2
    assert np.allclose(area[d.is_open], math.pi * d.R_mm**2, rtol=0.02)
    write_design(tmp_path / "d.toml", disc_design(plan, d), force=True)
    back = read_design(tmp_path / "d.toml")
    assert np.allclose(back.pattern_centres_xy_mm(), d.centres_mm) and back.R_mm == d.R_mm
    hard = disc_code(plan_capture(design_spec(SPEC, tmp_path / "d.toml")), 32)
    assert np.mean((code >= 0.5) != (hard > 0)) < 0.01  # cells whose centre is on the rim
    assert not np.array_equal(hard, hard[:, ::-1, :])  # y matters: not symmetric


def test_every_disc_stays_inside_the_lens(setup):
    plan, _, grid = setup
    d = plan_discs(plan)
    far = Discs(d.centres_mm * 0 + [[9.0, -9.0]], 20.0, d.is_open)
    got = project_inside(far, grid, True)
    assert got.R_mm == grid.R_max_mm
    assert np.all(np.hypot(*got.centres_mm.T) + got.R_mm <= grid.R_max_mm + 1e-12)
    kept = project_inside(d, grid, False)  # the prototype is inside: untouched
    assert np.allclose(kept.centres_mm[d.is_open], d.centres_mm[d.is_open])
    small = project_inside(Discs(d.centres_mm, 0.0, d.is_open), grid, True)
    assert small.R_mm == pytest.approx(grid.R_min_mm)  # one LCoS pixel


def test_the_search_climbs_and_fixed_light_keeps_the_radius(setup):
    plan, problem, grid = setup
    d = plan_discs(plan)
    fixed = disc_search([problem], {"prototype": d}, grid, iterations=6)
    assert fixed.rows[-1][2] > fixed.rows[0][2] and fixed.discs.R_mm == d.R_mm
    free = disc_search([problem], {"prototype": d}, grid, iterations=6, light="free")
    assert free.discs.R_mm != d.R_mm and free.evaluations == 6


def test_a_discs_search_with_held_out_stores_from_the_command_line(store, tmp_path, capsys):
    held = [render_lightfield(StoreSpec(replace(SPEC, seed=s), alpha=1.0),
                              tmp_path / f"held{s}", progress=False) for s in (11, 12)]  # fmt: skip
    out = tmp_path / "opt"
    args = ["optimize", "--lightfield", str(store.folder), "--space", "discs", "--cells", "8",
            "--iterations", "3", "--starts", "2", "--noise-draws", "1", "--quiet",
            "--held-out", *[str(h.folder) for h in held], "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "Held-out stores" in text and "paired per held-out store" in text
    cam = read_design(out / "design.toml")
    assert cam.schedule_kind == "centres" and cam.pattern_masks is None
    doc = json.loads((out / "report.json").read_text())
    assert [r["where"] for r in doc["held_out"]] == [str(h.folder) for h in held for _ in (0, 1)]
    moving = doc["held_out_vs_prototype"]["psnr_moving_db"]
    found = [r["psnr_moving_db"] for r in doc["held_out"] if r["design"] == "found discs"]
    proto = [r["psnr_moving_db"] for r in doc["held_out"] if r["design"] == "prototype"]
    assert moving[0] == pytest.approx(np.mean(np.subtract(found, proto))) and moving[3] == 2
    assert doc["train"][1]["light_rel"] == pytest.approx(1.0, abs=1e-9)  # fixed light: same R
    assert (out / "patterns.png").stat().st_size > 0


@pytest.mark.parametrize("extra, says", [
    (["--space", "discs", "--levels", "4"], "--levels: only a search with --space bitmap"),
    (["--space", "discs", "--held-out", "HELD1"], "--held-out: at least 2 stores"),
    (["--space", "discs", "--held-out", "STORE", "HELD1"], "--held-out: a store the search"),
    (["--space", "centres", "--held-out", "HELD1"], "--held-out: only a search with --space"),
    (["--space", "discs", "--max-still-loss", "-1"], "--max-still-loss: a finite number >= 0"),
    (["--space", "bitmap", "--lcos-switching", "1"], "--lcos-switching: only a search with"),
    (["--space", "discs", "--lcos-switching", "9"], "--lcos-switching (9 ms) must be at most"),
])  # fmt: skip
def test_bad_discs_flags_get_one_line(store, tmp_path, capsys, extra, says):
    held = tmp_path / "held1"
    if any("HELD1" in e for e in extra):
        render_lightfield(StoreSpec(replace(SPEC, seed=21), alpha=1.0), held, progress=False)
    extra = [str(held) if e == "HELD1" else str(store.folder) if e == "STORE" else e
             for e in extra]  # fmt: skip
    out = tmp_path / "opt"
    assert main(["optimize", "--lightfield", str(store.folder), *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def _row(design, where, moving, still):
    return {"design": design, "where": where, "psnr_moving_db": moving, "psnr_static_db": still}


def test_the_choice_keeps_the_best_eligible_design_or_the_prototype():
    """The real pipeline's rows decide (:mod:`~pacam_render.optimize.cell_select`): the best
    mean score wins; a design that loses more still PSNR than allowed is not eligible; where
    nothing eligible beats the prototype, it is kept (ties too)."""
    from pacam_render.optimize.cell_select import _pick

    rows = [_row("prototype", "a", 20.0, 25.0), _row("prototype", "b", 18.0, None),
            _row("from x", "a", 21.0, 23.0), _row("from x", "b", 19.0, None),
            _row("from y", "a", 20.4, 24.9), _row("from y", "b", 18.2, None)]  # fmt: skip
    names = ["prototype", "from x", "from y"]
    assert _pick(rows, names, 0.0, None)["chosen"] == "from x"  # moving 20.0 vs 19.3
    got = _pick(rows, names, 0.0, 1.0)
    assert got["chosen"] == "from y" and not got["scores"]["from x"]["eligible"]
    assert got["scores"]["from y"]["still_db"] == 24.9  # the stores with still pixels only
    assert _pick(rows, names, 0.0, 0.05)["chosen"] == "prototype"  # y loses 0.1 dB of still
    w = _pick(rows, names, 1.0, None)["scores"]["from x"]["value_db"]
    assert w == pytest.approx((20.0 + 23.0) / 2)  # (moving + still) / 2, means over stores
    tie = [_row("prototype", "a", 20.0, 25.0), _row("from x", "a", 20.0, 25.0)]
    assert _pick(tie, ["prototype", "from x"], 0.0, None)["chosen"] == "prototype"


def test_the_worst_choice_takes_the_smallest_gain_not_the_mean():
    """With the "worst" aggregate the choice pools as the search does: the prototype's mean
    plus the soft minimum of the gains store by store. A design that gains 2 dB on one store
    and loses 1 on the other wins on the mean and loses to one that gains 0.3 on both."""
    from pacam_render.optimize.cell_objective import WORST_SOFTNESS_DB
    from pacam_render.optimize.cell_select import _pick

    rows = [_row("prototype", "a", 20.0, None), _row("prototype", "b", 18.0, None),
            _row("from x", "a", 22.0, None), _row("from x", "b", 17.0, None),
            _row("from y", "a", 20.3, None), _row("from y", "b", 18.3, None)]  # fmt: skip
    names = ["prototype", "from x", "from y"]
    assert _pick(rows, names, 0.0, None)["chosen"] == "from x"
    got = _pick(rows, names, 0.0, None, "worst")
    assert got["chosen"] == "from y"
    tau = WORST_SOFTNESS_DB
    assert got["scores"]["from y"]["value_db"] == pytest.approx(19.3)  # equal gains: 19 + 0.3
    x = 19.0 - tau * np.log((np.exp(-2.0 / tau) + np.exp(1.0 / tau)) / 2)  # closed form
    assert got["scores"]["from x"]["value_db"] == pytest.approx(x)
    assert got["scores"]["from x"]["moving_db"] == pytest.approx(19.5)  # the table: the mean


def test_the_soft_minimum_is_its_closed_form_at_extreme_gains():
    """Gains far apart (1000 tau) and huge (1e6 dB): no overflow; the soft minimum is the
    smallest gain plus tau log 2 (the mean of exp(0) and exp(-1000)), its weights (1, 0);
    equal gains give the gain itself and equal weights."""
    from pacam_render.optimize.cell_objective import WORST_SOFTNESS_DB, soft_minimum

    tau = WORST_SOFTNESS_DB
    for g in (-1e6, 0.0, 1e6):
        v, w = soft_minimum(np.array([g, g + 1000 * tau]))
        assert np.isfinite(v) and v == pytest.approx(g + tau * np.log(2), abs=1e-6 * max(1, abs(g)))
        assert w == pytest.approx([1.0, 0.0])
    v, w = soft_minimum(np.full(4, 3.0))
    assert v == pytest.approx(3.0) and w == pytest.approx([0.25] * 4)


def test_open_times_with_a_switching_lcos_are_the_blend_s_closed_form():
    """Four windows of 2 ms, t_s = 1 ms: a window's code loses, on average, 0.5 ms of its own
    first ms to the previous code and is still shown 0.5 ms into the next window; window 0
    only gains, the last only loses."""
    from pacam_render.optimize.cell_objective import open_times

    got = open_times([2.0, 2.0, 2.0, 2.0], 1.0) * 8.0
    assert np.allclose(got, [2.5, 2.0, 2.0, 1.5]) and np.allclose(open_times([2.0] * 4), 0.25)


def test_a_discs_search_with_a_switching_lcos(store, tmp_path):
    out = tmp_path / "sw"
    args = ["optimize", "--lightfield", str(store.folder), "--space", "discs", "--cells", "8",
            "--iterations", "2", "--starts", "1", "--noise-draws", "1", "--quiet",
            "--lcos-switching", "1.0", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    doc = json.loads((out / "report.json").read_text())
    assert doc["problem"]["lcos_switching_ms"] == 1.0
    assert read_design(out / "design.toml").schedule_kind == "centres"


def test_paired_intervals_count_scenes_not_their_render_seeds():
    """Two render seeds of one scene are not independent: :func:`paired` averages a unit's
    places first, so its interval is scipy's t interval over the scenes' mean differences, and
    n counts scenes; without units, each place counts (the old, too narrow interval)."""
    from scipy import stats

    from pacam_render.optimize.cell_report import paired

    rng = np.random.default_rng(3)
    scene_gain = rng.normal(0.5, 1.0, 6)
    rows = []
    for i, g in enumerate(scene_gain):
        for j in range(2):
            base, d = 20.0 + i, g + rng.normal(0.0, 0.05)
            for name, v in (("prototype", base), ("found", base + d)):
                rows.append({**_row(name, f"{i}/{j}", v, None), "unit": str(i)})
    means = [np.mean([r["psnr_moving_db"] for r in rows if r["unit"] == str(i)
                      and r["design"] == "found"]) - (20.0 + i) for i in range(6)]  # fmt: skip
    lo, hi = stats.t.interval(0.95, 5, loc=np.mean(means), scale=stats.sem(means))
    m, a, b, n = paired(rows)["found"]
    assert n == 6 and m == pytest.approx(np.mean(means)) and (a, b) == pytest.approx((lo, hi))
    flat = paired([{k: v for k, v in r.items() if k != "unit"} for r in rows])["found"]
    assert flat[3] == 12 and flat[2] - flat[1] < 0.8 * (hi - lo)


@pytest.mark.render
def test_each_row_states_its_render_noise_as_a_share_of_the_sensors():
    """A report row's ``render_noise_ratio`` is the capture's Monte Carlo sigma over the
    sensor's: it falls as 1/sqrt(spp) (4x the samples, half the ratio; from 64 spp up, where
    the plan takes the spp asked), and a capture rendered to a noise target
    (:class:`SensorTarget`) reports a ratio within it. Designs compared at unequal ratios are
    compared in unequal noise (issue 58: a bitmap keeps 2-3x the prototype's render noise at
    one spp)."""
    import warnings

    from pacam_render.exposure.direct import render_capture
    from pacam_render.optimize.cell_report import design_row
    from pacam_render.sensor.apply import SensorTarget

    sensor, level = "grasshopper-icx285-mono", 300.0
    ratios = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for spp in (64, 256):
            cap = render_capture(replace(SPEC, spp=spp, grey=True), progress=False, truth=True)
            ratios.append(design_row("p", "w", cap, cap, sensor, level, (0,))["render_noise_ratio"])
        target = SensorTarget(0.5 * ratios[1], ((sensor, level),))
        cap = render_capture(replace(SPEC, spp=64, grey=True), progress=False, truth=True,
                             target=target)  # fmt: skip
    assert 0.4 < ratios[1] / ratios[0] < 0.6, ratios
    got = design_row("p", "w", cap, cap, sensor, level, (0,))["render_noise_ratio"]
    assert got <= 1.05 * target.ratio, (got, target.ratio)
