"""The schedule optimiser (issue 17): the closed-form objective against its references, the
designed schedule through the model, the plugin and the CLI, and bad input."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.experiments import simulate as E
from pacam_render.model.camera import prototype
from pacam_render.model.schedule_file import apply_schedule, read_schedule
from pacam_render.optimize.objective import PRIOR_C, SOFTMAX_DB, Objective, make_grid
from pacam_render.optimize.search import Problem, build_objective, multi_start, reference_design
from pacam_render.psf.analytic import design_psf

PAPER = dict(sensor="paper", light_level=None, r_px=2.0)


def _problem(s_max=2.88, depths=(500.0, 500.0), **kw):
    return Problem(s_max, depths, 16, **{**PAPER, **kw})


def _objective(p, n_speeds=9, n_depths=1):
    return build_objective(p, reference_design(p), n_speeds, n_depths)


@pytest.mark.parametrize("free_radius, depths", [(False, (500.0, 500.0)), (True, (450.0, 560.0))])
def test_gradient_matches_central_differences(free_radius, depths):
    p = _problem(depths=depths, sensor="grasshopper-icx285", r_px=2.0, free_radius=free_radius)
    obj = _objective(p, 7, 3)
    rng = np.random.default_rng(3)
    theta = np.clip(
        obj.pack(obj.ref.pattern_centres_xy_mm()[:, 0], obj.ref.beta_px_per_mm, obj.ref.R_mm)
        + rng.normal(0, 0.05, obj.n + 1 + free_radius),
        *zip(*obj.bounds()),
    )
    _, g = obj.loss(theta)
    h = 1e-6
    num = [
        (obj.loss(theta + h * e)[0] - obj.loss(theta - h * e)[0]) / (2 * h)
        for e in np.eye(theta.size)
    ]
    assert np.allclose(g, num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


def test_prior_level_is_the_photographs_spectrum():
    """PRIOR_C against the 13 photographs' mean power spectrum (geometric mean over 0.02-0.5)."""
    import scipy.fft as sfft

    imgs = E.load_images()
    n = imgs.shape[1]
    win = np.outer(np.hanning(n), np.hanning(n))
    win /= np.sqrt((win**2).mean())
    P = np.mean([np.abs(sfft.fft2((i - i.mean()) * win)) ** 2 / n**2 for i in imgs], axis=0)
    f2 = sfft.fftfreq(n)[:, None] ** 2 + sfft.fftfreq(n)[None, :] ** 2
    m = (f2 > 0.02**2) & (f2 < 0.25)
    c = np.exp(np.mean(np.log(P[m] * (f2[m] + n**-2.0))))
    assert c == pytest.approx(PRIOR_C, rel=0.05)


def test_predicted_psnr_follows_image_domain_wiener():
    """The parabola's predicted PSNR against blurring, noising and Wiener-deblurring
    photographs with its analytic kernels (Fig. 6's set-up, 6 photographs): within 3 dB at
    every speed (the closed form is optimistic, most at the fast end), and the same ups and
    downs across speed (correlation > 0.9)."""
    p = _problem()
    obj = _objective(p)
    speeds = np.array([0.0, 0.171, 0.321, 1.133, 2.129])
    grid = make_grid(2.88, (500.0, 500.0), 1, 1, 200, 8)
    obj = Objective(obj.ref, grid.__class__(speeds, grid.depths_mm, 0, 0, grid.shape),
                    lambda R: 1e-4)  # fmt: skip
    theta = obj.pack(obj.ref.pattern_centres_xy_mm()[:, 0], obj.ref.beta_px_per_mm)
    pred = obj.psnr_db(theta)[0]
    imgs = E.load_images(6)
    k0 = design_psf(obj.ref, "coded", 0.0)
    ks = [design_psf(obj.ref, "coded", s) for s in speeds]
    scenes = E.Scenes(imgs, max(max(k.shape) for k in [k0, *ks]) // 2 + 1)
    sim = np.array([E.simulate(scenes, k, k0, E.gaussian_noise(0.01), 0, 16).mean() for k in ks])
    assert np.all(np.abs(pred - sim) < 3.0), (pred, sim)
    assert np.corrcoef(pred, sim)[0, 1] > 0.9, (pred, sim)


def test_designed_parabola_is_the_parabola():
    d = prototype()
    designed = d.with_(pattern_centres_mm=tuple(map(tuple, d.pattern_centres_xy_mm())))
    for s in (0.0, 0.7, 1.3):
        k = design_psf(d, "coded", s, origin="pinhole")
        assert (
            np.abs(design_psf(designed, "coded", s, size=k.shape, origin="pinhole") - k).sum()
            < 1e-12
        )


def test_vertical_offset_moves_rows_by_beta():
    """A pattern opened at y mm images beta_px y rows lower (Eq. 8 in y); the mass stays 1."""
    d = prototype()
    c = d.pattern_centres_xy_mm()
    c[3, 1] = 1.0
    k = design_psf(d.with_(pattern_centres_mm=tuple(map(tuple, c))), "coded", 0.0, origin="pinhole")
    rows = k.sum(axis=1)
    centre = k.shape[0] // 2
    y = (np.arange(k.shape[0]) - centre) @ rows
    assert k.sum() == pytest.approx(1.0)
    assert y == pytest.approx(d.beta_px_per_mm * 1.0 / 16, rel=2e-3)  # pixel binning


@pytest.mark.parametrize("where", ["in focus", "far bound", "near bound", "loud", "quiet"])
def test_objective_stays_finite_at_the_extremes(where):
    """beta_0 = 0 (no coding: the discs collapse to a point), the focus at either bound, noise
    10^4 x louder or 10^-6 x quieter: a finite error, a finite gradient, PSNR within reason."""
    p = _problem()
    ref = reference_design(p)
    scale = {"loud": 1e4, "quiet": 1e-6}.get(where, 1.0)
    obj = Objective(ref, _objective(p).grid, lambda R: 1e-4 * scale)
    lo, hi = obj.bounds()[obj.n]
    b = {"in focus": 0.0, "far bound": lo, "near bound": hi}.get(where, -1.0)
    theta = obj.pack(ref.pattern_centres_xy_mm()[:, 0], b * obj.beta_ref)
    L, g = obj.loss(theta)
    psnr = obj.psnr_db(theta)
    assert np.isfinite(L) and np.all(np.isfinite(g))
    assert np.all((psnr > -10) & (psnr < 120))


def test_optimiser_beats_its_start_and_is_reproducible():
    p = _problem()
    obj = _objective(p)
    runs = [multi_start(obj, 2, 15, seed=4, progress=False) for _ in range(2)]
    (starts, best), (_, best2) = runs
    assert np.array_equal(best.theta, best2.theta)
    p0 = obj.psnr_db(starts[0].theta0)
    assert best.worst_db > p0.min() + 0.3
    X, _, R = obj.unpack(best.theta)
    assert np.all(np.abs(X) + R <= obj.R_max * (1 + 1e-9))


def _write(tmp_path, **doc):
    base = {
        "centres_mm": [[x, 0.0] for x in np.linspace(-3, 3, 16)],
        "radius_mm": 1.0,
        "focus_distance_mm": 750.0,
        "n_patterns": 16,
    }
    base.update(doc)
    path = tmp_path / "schedule.json"
    path.write_text(json.dumps({k: v for k, v in base.items() if v is not None}))
    return path


@pytest.mark.parametrize(
    "doc, key",
    [
        ({"n_patterns": 1}, "'n_patterns'"),
        ({"n_patterns": 17}, "'n_patterns'"),
        ({"radius_mm": None}, "radius_mm"),
        ({"radius_mm": -1}, "radius_mm"),
        ({"radii_mm": [1.0] * 15 + [2.0], "radius_mm": None}, "radii_mm"),
        ({"centres_mm": [[0, 0]] * 15}, "centres_mm"),
        ({"focus_distance_mm": "far"}, "focus_distance_mm"),
    ],
)
def test_bad_schedule_file_names_the_key(tmp_path, doc, key):
    with pytest.raises(ParameterError, match=key):
        read_schedule(_write(tmp_path, **doc))


def test_opening_outside_the_lens_is_named(tmp_path):
    sched = read_schedule(_write(tmp_path, centres_mm=[[6.5, 0.0]] * 16))
    with pytest.raises(ParameterError, match=r"centres_mm\[0\].*outside the lens"):
        apply_schedule(prototype(), sched)


def test_unreadable_schedule(tmp_path):
    bad = tmp_path / "schedule.json"
    bad.write_text("{not json")
    with pytest.raises(ParameterError, match="`schedule` .*schedule.json is not valid JSON"):
        read_schedule(bad)


@pytest.mark.parametrize(
    "args, words",
    [
        (["--max-velocity", "500"], "no opening covers it"),
        (
            ["--max-velocity", "1", "--n-patterns", "1"],
            "--n-patterns must be an integer in [2, 16]",
        ),
        (["--max-velocity", "1", "--n-patterns", "17"], "365 per second"),
        (["--max-velocity", "1", "--sensor", "paper", "--light-level", "300"], "--light-level"),
        (["--max-velocity", "1", "--depth-range", "600,500"], "NEAR <= FAR"),
        (["--max-velocity", "-1"], "--max-velocity"),
        (["--max-velocity", "1", "--seed", "-1"], "--seed"),
        (["--max-velocity", "1", "--starts", "0"], "--starts"),
        (["--max-velocity", "1", "--f-number", "5", "--r-px", "2"], "not both"),
    ],
)
def test_optimize_cli_refuses_bad_input(tmp_path, capsys, args, words):
    assert main(["optimize", *args, "--out", str(tmp_path / "o")]) == 2
    assert words in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_optimize_cli_writes_every_output(tmp_path, capsys):
    out = tmp_path / "o"
    args = ["optimize", "--max-velocity", "1.0", "--quick", "--starts", "1", "--iterations", "3"]
    assert main([*args, "--quiet", "--out", str(out)]) == 0
    doc = json.loads((out / "schedule.json").read_text())
    for key in ("centres_mm", "radius_mm", "focus_distance_mm", "n_patterns", "objective_worst",
                "objective_mean", "parabola_objective_worst", "parabola_objective_mean",
                "max_velocity_px_per_ms", "depth_range_mm"):  # fmt: skip
        assert key in doc
    assert doc["objective_worst"] >= doc["parabola_objective_worst"] - 1e-9
    assert len(list((out / "lcos").glob("pattern_*.png"))) == 16
    import imageio.v3 as iio

    m = iio.imread(out / "lcos" / "pattern_00.png")
    assert m.shape == (1024, 1280) and set(np.unique(m)) <= {0, 255}
    assert all((out / f).is_file() for f in ("report.md", "psnr.png", "psf.png", "schedule.png"))
    # the report's soft worst case is the log-sum-exp of the grid it prints (schedule.json)
    report = (out / "report.md").read_text()
    p = np.asarray(doc["predicted_psnr_db"])
    soft = -SOFTMAX_DB * np.log(np.mean(np.exp(-p / SOFTMAX_DB)))
    printed = re.search(r"([0-9.]+) dB at the best start's end", report)
    assert printed and float(printed.group(1)) == pytest.approx(soft, abs=0.006)
    assert p.min() <= soft <= p.min() + SOFTMAX_DB * np.log(p.size)
    assert main([*args, "--quiet", "--out", str(out)]) == 2  # no overwrite without --force
    sched = read_schedule(out / "schedule.json")
    cam = apply_schedule(prototype(), sched)
    assert cam.designed and cam.R_mm == pytest.approx(doc["radius_mm"])


@pytest.mark.render
def test_rendered_designed_psf_matches_analytic():
    """A designed (non-parabolic, with a vertical offset) schedule's rendered PSF at three
    speeds matches its analytic kernel at the Monte Carlo floor (two seeds' distance)."""
    from pacam_render.psf_render.render import render_psf
    from pacam_render.restore.metrics import rel_l1

    d = prototype().with_(width_px=320, height_px=240)
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, 16) * (d.R_max_mm - d.R_mm)
    c = np.stack([x, np.zeros(16)], axis=1)
    c[5, 1] = 2.0
    designed = d.with_(pattern_centres_mm=tuple(map(tuple, c)))
    for s in (0.0, 0.3, -0.5):
        k = design_psf(designed, "coded", s, origin="t0")
        a = render_psf(designed, "coded", s, size=k.shape, spp=64, seed=1).kernel
        b = render_psf(designed, "coded", s, size=k.shape, spp=64, seed=2).kernel
        floor = rel_l1(a, b)
        assert rel_l1(a, k) < 1.5 * floor, (s, rel_l1(a, k), floor)


def test_report_explains_a_focus_at_infinity_only_there():
    """The far-focus note gives |beta_0| = f_px / Z_0 at the bound and its defocus."""
    from types import SimpleNamespace

    from pacam_render.optimize.outputs import _reading_notes

    doc = dict(speeds_px_per_ms=[-1.0, 0.0, 1.0], depths_mm=[500.0], best_start=0,
               predicted_psnr_db=[[20.0, 25.0, 21.0]], object_depth_mm=500.0,
               parabola_predicted_psnr_db=[[22.0, 24.0, 19.0]], radius_mm=0.766,
               parabola={"r_px": 2.0})  # fmt: skip
    start = SimpleNamespace(index=0, iterations=[(0, 0.0, -20.1)], worst_db=20.0)
    f_px = 1507.7455
    far = dict(doc, focus_distance_mm=5e5, beta_px_per_mm=-0.999 * f_px / 500, r_px=2.31)
    text = "\n".join(_reading_notes(far, [start]))
    assert "s = -1.00 px/ms" in text and "s = 1.00 px/ms" in text  # each schedule's worst
    assert "Focus at infinity" in text and f"({0.999 * f_px / 500:.2f} px/mm here)" in text
    near = dict(doc, focus_distance_mm=3717.4, beta_px_per_mm=-2.61, r_px=2.0)
    assert "Focus at infinity" not in "\n".join(_reading_notes(near, [start]))
