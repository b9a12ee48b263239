"""A schedule's own figures (issue 35, item 3): a_i and the invariant range fitted to the held
patterns' image offsets, against closed forms; the report and pacam optimize use them."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model import schedule as sch
from pacam_render.model.camera import prototype
from pacam_render.model.modes import pattern_offsets_px
from pacam_render.model.report import design_report
from pacam_render.model.schedule_fit import (
    FIGURE_KEYS,
    fit_held_parabola,
    parabola_fit_ratio,
    schedule_figures,
)

PROTO = prototype()

OPT8_CENTRES_X = (4.99173, -0.22832980088555657, -4.026783467642118, -4.99173,
                  -4.99173, -4.026783467642116, -0.22832980088555535, 4.99173)  # fmt: skip
"""``pacam optimize --max-velocity 1.4 --n-patterns 8 --quick`` (seed 0): the issue's
schedule (Eq. 18 -0.0690 px/ms^2, 1.553 px/ms; rendered centroids -0.0945)."""
OPT8_FOCUS_MM = 1191.7618265073754


def _designed(xs, ys=None, **kw):
    ys = np.zeros(len(xs)) if ys is None else ys
    return PROTO.with_(
        n_patterns=len(xs),
        pattern_centres_mm=tuple(zip(map(float, xs), map(float, ys))),
        name="designed",
        quoted_a_i_px_per_ms2=None,
        **kw,
    )


def _window_means(e, u0, b, a):
    """Window means of u0 + b t + a t^2 / 2 over the windows with edges ``e``."""
    e0, e1 = e[:-1], e[1:]
    return u0 + b * (e0 + e1) / 2 + a * (e0**2 + e0 * e1 + e1**2) / 6


@pytest.mark.parametrize("n", [3, 5, 8, 16, 33])
@pytest.mark.parametrize("a, b, u0", [(-0.0945, 0.0, 8.7), (0.256, -0.31, -2.0), (1e-4, 2.0, 0)])
def test_any_parabola_is_recovered_exactly(n, a, b, u0):
    """From its window means, and from its mid-time values (a constant a h^2 / 24 apart)."""
    e = sch.pattern_edges_ms(22.5, n)
    for u in (_window_means(e, u0, b, a), u0 + b * (t := (e[:-1] + e[1:]) / 2) + a * t**2 / 2):
        f = fit_held_parabola(e, u)
        assert f["a"] == pytest.approx(a, abs=1e-9)
        assert f["b"] == pytest.approx(b, abs=1e-9)
        assert f["rms_px"] == pytest.approx(0.0, abs=1e-9)
        assert f["dof"] == n - 3 and f["reason"] is None
    assert fit_held_parabola(e, _window_means(e, u0, b, a))["u0"] == pytest.approx(u0, abs=1e-9)


def test_a_designed_schedule_on_a_known_parabola_recovers_it():
    """Centres from u_k = a t_k^2 / 2 + b t_k + c (over beta_px): the fit gives a, to 1e-9."""
    n, a, b = 12, -0.012, 0.02
    t = sch.pattern_mid_times_ms(PROTO.T_ms, n)
    u = a * t**2 / 2 + b * t + 1.0
    cam = _designed(u / PROTO.beta_px_per_mm)
    f = schedule_figures(cam)
    assert f["a_i_fitted_px_per_ms2"] == pytest.approx(a, abs=1e-9)
    assert f["velocity_range_fitted_px_per_ms"] == pytest.approx(abs(a) * PROTO.T_ms, abs=1e-9)
    assert f["velocity_centre_fitted_px_per_ms"] == pytest.approx(-b, abs=1e-9)
    assert f["fit_rms_residual_px"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("n", [3, 4, 8, 16, 64])
def test_the_paper_parabola_gives_eq18(n):
    """Patterns centred on Eq. 11's parabola at their mid-times keep its curvature exactly."""
    cam = PROTO.with_(n_patterns=n)
    f = schedule_figures(cam)
    assert f["schedule"] == "parabola" and f["n_patterns"] == n
    assert f["a_i_fitted_px_per_ms2"] == pytest.approx(cam.a_i_px_per_ms2, rel=1e-12)
    assert f["velocity_range_fitted_px_per_ms"] == pytest.approx(
        cam.velocity_range_px_per_ms, rel=1e-12
    )
    assert f["fit_rms_residual_px"] < 1e-12
    assert abs(f["velocity_centre_fitted_px_per_ms"]) < 1e-12  # symmetric in time


@pytest.mark.parametrize("n", [3, 4, 8, 16, 64, 256])
def test_the_continuous_l2_fit_shrinks_a_by_the_closed_form(n):
    """Minimising the whole integral of (p - u)^2 gives (1 - 1/N^2)(1 - 4/N^2) of Eq. 18."""
    cam = PROTO.with_(n_patterns=n)
    e = sch.pattern_edges_ms(cam.T_ms, n)
    u = pattern_offsets_px(cam)[:, 0]
    a = fit_held_parabola(e, u, "continuous_l2")["a"]
    assert a / cam.a_i_px_per_ms2 == pytest.approx(parabola_fit_ratio(n), rel=1e-10)


def test_the_continuous_l2_ratio_by_brute_force_and_its_limit():
    """N = 16: a dense least-squares fit to the step function gives 0.98053; N -> infinity: 1,
    with 1 - ratio ~ 5 / N^2."""
    cam = PROTO
    T = cam.T_ms
    u = pattern_offsets_px(cam)[:, 0]
    t = np.linspace(-T, T, 1_600_000, endpoint=False) + T / 1_600_000  # midpoints, 1e5 a window
    step = u[sch.pattern_index(t, T, 16)]
    a = 2 * np.polyfit(t, step, 2)[0]
    assert a / cam.a_i_px_per_ms2 == pytest.approx(parabola_fit_ratio(16), abs=1e-6)
    assert parabola_fit_ratio(16) == pytest.approx(255 * 252 / 256**2, rel=1e-15)  # 0.98053
    assert parabola_fit_ratio(2) == 0.0
    for n in (100, 1000, 10000):
        assert (1 - parabola_fit_ratio(n)) * n**2 == pytest.approx(5.0, abs=5 / n)


def test_a_line_has_no_curvature():
    t = sch.pattern_mid_times_ms(PROTO.T_ms, 10)
    cam = _designed(0.1 * t - 1.0)  # mm, inside the lens
    f = schedule_figures(cam)
    assert f["a_i_fitted_px_per_ms2"] == pytest.approx(0.0, abs=1e-12)
    assert f["velocity_range_fitted_px_per_ms"] == pytest.approx(0.0, abs=1e-12)
    assert f["velocity_centre_fitted_px_per_ms"] == pytest.approx(
        -0.1 * PROTO.beta_px_per_mm, rel=1e-9
    )
    assert f["fit_rms_residual_px"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("xs", [(1.0, -1.0), (2.0,)])
def test_fewer_than_three_patterns_give_none_with_a_reason(xs):
    f = schedule_figures(_designed(xs))
    for k in ("a_i_fitted_px_per_ms2", "velocity_range_fitted_px_per_ms", "fit_rms_residual_px"):
        assert f[k] is None
    assert f"{len(xs)} pattern" in f["fit_undefined_reason"]
    assert "undefined" in f["fit_undefined_reason"]
    json.dumps(f, allow_nan=False)  # never NaN
    if len(xs) == 2:
        assert "2.018 px" in f["fit_undefined_reason"]  # the jump: beta_px x 2 mm
    text = design_report(_designed(xs))
    assert f"{len(xs)} patterns" in text and "undefined" in text


def test_the_optimised_8_pattern_schedule():
    """The issue's schedule: Eq. 18 recorded -0.0690 and 1.553 px/ms; the fit to its own
    patterns gives -0.0945 (as the rendered centroids did) and 2.13 px/ms."""
    cam = _designed(OPT8_CENTRES_X, focus_distance_mm=OPT8_FOCUS_MM)
    assert cam.a_i_px_per_ms2 == pytest.approx(-0.0690, abs=5e-5)
    f = schedule_figures(cam)
    assert f["schedule"] == "designed" and f["n_patterns"] == 8
    assert f["a_i_fitted_px_per_ms2"] == pytest.approx(-0.09451, abs=5e-5)
    assert f["velocity_range_fitted_px_per_ms"] == pytest.approx(2.1264, abs=5e-4)
    assert f["fit_rms_residual_px"] == pytest.approx(0.4665, abs=5e-4)
    assert f["fit_dof"] == 5
    assert np.allclose(f["pattern_offsets_px"], pattern_offsets_px(cam), rtol=0, atol=1e-12)
    assert f["pattern_edges_ms"] == pytest.approx(np.linspace(-22.5, 22.5, 9).tolist())
    assert list(f) == list(FIGURE_KEYS)
    assert all(isinstance(v, (int, float, str, list, type(None))) for v in f.values())
    assert all(type(v) in (int, float) for v in f.values() if isinstance(v, (int, float)))
    json.dumps(f, allow_nan=False)
    text = design_report(cam)
    assert "8 patterns" in text and "16 pattern" not in text and "16 opening" not in text
    assert "fitted to the schedule's image trajectory" in text
    assert "-0.0945" in text and "2.126" in text  # fitted a_i and range
    assert "not this schedule" in text  # Eq. 18's figures are labelled as the parabola's


def test_the_report_shows_eq18_and_the_fit_for_the_parabola():
    text = design_report(PROTO)
    assert "Eq. 18" in text and "image acceleration, fitted" in text
    assert "16 patterns" in text and "open fraction" in text
    assert "0.0807581" in text  # (145.5 / 512)^2


def test_a_two_dimensional_schedule_shows_its_vertical_shifts():
    xs = np.linspace(-3, 3, 5)
    cam = _designed(xs, ys=(0.0, 0.5, 1.0, 0.5, 0.0))
    f = schedule_figures(cam)
    assert f["pattern_offsets_px"][2][1] == pytest.approx(PROTO.beta_px_per_mm * 1.0)
    assert "v shift px" in design_report(cam)


def test_open_fraction_disc_and_given_areas():
    f = schedule_figures(PROTO)
    assert f["open_fraction"] == pytest.approx((145.5 / 512) ** 2, rel=1e-12)
    assert f["open_area_mm2_mean"] == pytest.approx(PROTO.open_area_mm2, rel=1e-12)
    full = np.pi * PROTO.R_max_mm**2
    areas = np.linspace(0.1, 0.3, 16) * full
    g = schedule_figures(PROTO, open_areas_mm2=areas)
    assert g["open_fraction"] == pytest.approx(0.2, rel=1e-12)  # equal windows: the mean
    assert g["open_area_source"] == "per-pattern open areas (given)"
    for bad in (areas[:3], -areas, areas * 10, np.full(16, np.nan)):
        with pytest.raises(ParameterError, match="open_areas_mm2"):
            schedule_figures(PROTO, open_areas_mm2=bad)


def test_a_dark_pattern_is_left_out_of_the_fit():
    n, a = 9, 0.02
    t = sch.pattern_mid_times_ms(PROTO.T_ms, n)
    cam = _designed((a * t**2 / 2 - 2.0) / PROTO.beta_px_per_mm)
    areas = np.full(n, PROTO.open_area_mm2)
    areas[4] = 0.0
    f = schedule_figures(cam, open_areas_mm2=areas)
    assert f["pattern_offsets_px"][4] is None and f["pattern_centres_mm"][4] is None
    assert f["a_i_fitted_px_per_ms2"] == pytest.approx(a, abs=1e-9)
    assert f["fit_dof"] == n - 1 - 3
    assert f["open_fraction"] == pytest.approx(schedule_figures(cam)["open_fraction"] * 8 / 9)
    json.dumps(f, allow_nan=False)
    areas[:7] = 0.0
    f = schedule_figures(cam, open_areas_mm2=areas)
    assert f["a_i_fitted_px_per_ms2"] is None and "7 of the 9 dark" in f["fit_undefined_reason"]


def test_bad_fit_input_is_refused():
    e = np.linspace(-1, 1, 5)
    with pytest.raises(ParameterError, match="edges"):
        fit_held_parabola(e, np.zeros(3))
    with pytest.raises(ParameterError, match="criterion"):
        fit_held_parabola(e, np.zeros(4), "cubic")
    with pytest.raises(ParameterError, match="finite"):
        fit_held_parabola(e, [0, np.nan, 0, 0])


def test_optimize_records_and_reports_the_true_pattern_count(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from pacam_render.cli import main
    from pacam_render.optimize import outputs

    texts = []

    def draw_only(path, draw, force):  # the plots' titles and legends, not the files
        fig = Figure()
        draw(fig)
        for ax in fig.axes:
            legend = ax.get_legend()
            texts.append(ax.get_title())
            texts.extend(t.get_text() for t in (legend.get_texts() if legend else []))
        return path

    monkeypatch.setattr(outputs, "save_figure", draw_only)
    out = tmp_path / "o"
    args = ["optimize", "--max-velocity", "1.4", "--n-patterns", "8", "--quick", "--starts", "1"]
    assert main([*args, "--iterations", "3", "--quiet", "--out", str(out)]) == 0
    doc = json.loads((out / "schedule.json").read_text())
    keys = ("a_i_fitted_px_per_ms2", "velocity_range_fitted_px_per_ms", "open_fraction",
            "fit_rms_residual_px", "fit_method", "parabola_velocity_range_px_per_ms")  # fmt: skip
    assert set(keys) <= set(doc)
    assert doc["velocity_range_fitted_px_per_ms"] == pytest.approx(
        abs(doc["a_i_fitted_px_per_ms2"]) * doc["exposure_ms"] / 2
    )
    report = (out / "report.md").read_text()
    assert "8 patterns" in report and not re.search(r"\b16 (patterns|openings)", report)
    assert "fitted to the schedule's image trajectory" in report
    assert f"{doc['a_i_fitted_px_per_ms2']:.4g}" in report
    assert "the 8 openings over time" in texts
    assert any(t.startswith("optimised (fitted a_i") for t in texts)


def test_the_examples_run():
    import doctest

    from pacam_render.model import schedule_fit

    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    result = doctest.testmod(schedule_fit, optionflags=flags, verbose=False)
    assert result.attempted >= 3 and result.failed == 0


def test_a_bitmap_schedule_is_fitted_from_its_masks():
    """Where the camera holds LCoS bitmaps (``pattern_masks``): their centroids and open areas;
    a black pattern is dark and left out."""
    from dataclasses import fields

    masks = pytest.importorskip("pacam_render.model.masks")
    if "pattern_masks" not in {f.name for f in fields(PROTO)}:
        pytest.skip("this CameraDesign has no bitmap schedules")
    cam = PROTO.with_(n_patterns=8)
    m = masks.disc_masks(cam.pattern_centres_xy_mm(), cam.R_mm, pitch_mm=cam.lcos_pitch_mm)
    m[2] = 0.0
    stack = masks.MaskStack(m, cam.lcos_pitch_mm)
    bitmap = cam.with_(pattern_masks=stack, R_mm=stack.equivalent_radius_mm())
    f = schedule_figures(bitmap)
    assert f["open_area_source"] == "the bitmaps' open areas"
    assert f["open_fraction"] == pytest.approx(
        stack.open_areas_mm2().mean() / (np.pi * cam.R_max_mm**2), rel=1e-12
    )
    assert f["pattern_centres_mm"][2] is None and f["fit_dof"] == 8 - 1 - 3
    # pixelated discs on the parabola: Eq. 18's curvature to the rasterisation
    assert abs(f["a_i_fitted_px_per_ms2"]) == pytest.approx(abs(cam.a_i_px_per_ms2), rel=1e-3)
    json.dumps(f, allow_nan=False)
    assert "8 patterns" in design_report(bitmap)
