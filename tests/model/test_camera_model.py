"""The analytic camera model (Sections 2.1-2.3) against closed forms and the paper's numbers."""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.model import camera, design, optics, schedule

PROTO = camera.prototype()


def test_prototype_matches_table1_and_section4():
    d = PROTO
    assert (d.width_px, d.height_px, d.fov_deg, d.n_patterns, d.exposure_ms) == (
        1280,
        960,
        46.0,
        16,
        45.0,
    )
    assert d.R_mm / d.lcos_pitch_mm == pytest.approx(145.5)
    assert d.F_number == pytest.approx(9.85, abs=0.01)
    assert d.r_px == pytest.approx(2.0, rel=1e-12)
    # PHYSICS.md: a_i = 4 r (R_max/R - 1) / T^2 = 20.1 / T^2 = 0.0398 for T = 22.5 ms
    assert abs(d.a_i_px_per_ms2) == pytest.approx(
        4 * 2 * (d.R_max_mm / d.R_mm - 1) / 22.5**2, rel=1e-12
    )
    assert abs(d.a_i_px_per_ms2) == pytest.approx(0.0398, abs=5e-5)
    assert d.velocity_range_px_per_ms == pytest.approx(0.896, abs=1e-3)


def test_eq9_in_mm_agrees_with_beta_px():
    """beta of Eq. 9 (sensor at Z_p, lens f from Eq. 7) divided by the pixel pitch is beta_px."""
    d = PROTO
    assert d.beta / d.pixel_pitch_mm == pytest.approx(d.beta_px_per_mm, rel=1e-12)
    # and the thin-lens equation puts the focal plane's image exactly on the sensor
    assert optics.image_distance_mm(d.lens_focal_length_mm, d.focus_distance_mm) == pytest.approx(
        d.Z_p_mm
    )


def test_beta_sign_flips_across_focal_plane_and_vanishes_in_focus():
    Zf = 750.0
    assert optics.beta_px_per_mm(500.0, Zf, 46, 1280) < 0  # focus behind the object
    assert optics.beta_px_per_mm(1000.0, Zf, 46, 1280) > 0
    assert optics.beta_px_per_mm(Zf, Zf, 46, 1280) == 0.0


def test_focus_for_defocus_round_trip():
    for side in ("far", "near"):
        Zf = optics.focus_for_defocus_mm(500.0, 3.0, 2.0, 46, 1280, side)
        b = optics.beta_px_per_mm(500.0, Zf, 46, 1280)
        assert abs(b) * 2.0 == pytest.approx(3.0)
        assert (b < 0) == (side == "far")
    with pytest.raises(ParameterError, match="focus at infinity"):
        optics.focus_for_defocus_mm(500.0, 100.0, 0.1, 46, 1280, "far")


def test_conversions_round_trip():
    assert optics.radius_to_f_number(
        optics.f_number_to_radius_mm(2.8, 39.0), 39.0
    ) == pytest.approx(2.8)
    assert optics.mm_to_lcos_px(optics.lcos_px_to_mm(145.5)) == pytest.approx(145.5)
    assert PROTO.f_number_focal_mm == pytest.approx(2 * PROTO.R_max_mm * PROTO.F_min)


def test_alpha_eq3_and_z_equals_f():
    assert optics.alpha(500.0, 10.0) == pytest.approx(-0.02)
    with pytest.raises(ParameterError, match="Z_mm must be > f_mm"):
        optics.image_distance_mm(39.0, 39.0)  # Z = f: image at infinity


def test_aperture_trajectory_eq11_15_17():
    d = PROTO
    R_max, R, T = d.R_max_mm, d.R_mm, d.T_ms
    x = schedule.aperture_centre_mm(np.array([-T, 0.0, T]), R_max, R, T)
    assert x == pytest.approx([R_max - R, -(R_max - R), R_max - R])
    assert d.delta_X_a_mm == pytest.approx(2 * (R_max - R))
    assert d.a_a_mm_per_ms2 == pytest.approx(2 * d.delta_X_a_mm / T**2)  # Eq. 16
    assert d.a_i_px_per_ms2 == pytest.approx(d.beta_px_per_mm * d.a_a_mm_per_ms2)  # Eq. 10
    ts = np.linspace(-T, T, 1001)
    assert np.all(np.abs(d.aperture_centre_mm(ts)) + R <= R_max + 1e-12)  # inside the lens


def test_sixteen_pattern_schedule():
    T = 22.5
    edges = schedule.pattern_edges_ms(T, 16)
    assert edges[0] == -T and edges[-1] == T and np.allclose(np.diff(edges), 45 / 16)
    eps = 1e-9
    assert schedule.pattern_index(edges[1] - eps, T, 16) == 0
    assert schedule.pattern_index(edges[1], T, 16) == 1
    assert schedule.pattern_index(T, T, 16) == 15 and schedule.pattern_index(-T, T, 16) == 0
    rows = PROTO.pattern_table()
    assert len(rows) == 16
    c = np.array([r["centre_mm"] for r in rows])
    assert np.allclose(c, c[::-1])  # symmetric about mid-exposure
    mids = schedule.pattern_mid_times_ms(T, 16)
    assert c == pytest.approx(0.5 * PROTO.a_a_mm_per_ms2 * mids**2 - (PROTO.R_max_mm - PROTO.R_mm))


def test_report_states_the_inconsistency():
    from pacam_render.model.report import design_report

    text = design_report(PROTO)
    assert "0.089" in text and "0.0398" in text
    assert "4.47 px" in text  # r needed at F9.85 in 45 ms
    assert "30.1 ms" in text  # exposure that would give 0.089 at r = 2 px


def test_coded_mode_needs_parallax():
    d = PROTO.with_(focus_distance_mm=500.0)
    assert d.r_px == 0.0
    with pytest.raises(ParameterError, match="no parallax"):
        d.require_parallax()


def test_opening_outside_lens_is_an_error():
    with pytest.raises(ParameterError, match="R_mm"):
        PROTO.with_(R_mm=PROTO.R_max_mm * 1.01)
    with pytest.raises(ParameterError, match="R_mm"):
        PROTO.with_(R_mm=-1.0)


@settings(max_examples=60, deadline=None)
@given(
    v=st.floats(0.05, 5.0),
    exposure=st.floats(5.0, 200.0),
    depth=st.floats(200.0, 5000.0),
    mode=st.sampled_from(["r", "F", "none"]),
)
def test_solver_covers_the_speed(v, exposure, depth, mode):
    kw = {"r": {"r_px": 2.0}, "F": {"f_number": 9.85}, "none": {}}[mode]
    try:
        d = design.solve(v, exposure_ms=exposure, object_depth_mm=depth, **kw)
    except ParameterError as exc:
        assert "limit" in str(exc)
        return
    assert d.velocity_range_px_per_ms == pytest.approx(v, rel=1e-9)
    assert d.R_mm <= d.R_max_mm and d.focus_distance_mm >= design.MIN_FOCUS_MM
    if mode == "r":
        assert d.r_px == pytest.approx(2.0, rel=1e-9)
    else:
        assert d.F_number == pytest.approx(9.85 if mode == "F" else PROTO.F_number, rel=1e-9)


def test_solver_limits_are_named():
    with pytest.raises(ParameterError, match="aperture limit"):
        design.solve(5.0, r_px=1e-3)
    with pytest.raises(ParameterError, match="f_number must be > F_min"):
        design.solve(1.0, f_number=2.8)
    with pytest.raises(ParameterError, match="focus limit"):
        design.solve(1.0, r_px=100.0, object_depth_mm=200.0)
    with pytest.raises(ParameterError, match="not both"):
        design.solve(1.0, r_px=2.0, f_number=9.0)


def test_cli_design_json_keys(capsys):
    assert main(["design", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in (
        "r_px beta_px_per_mm a_i_px_per_ms2 exposure_ms R_mm R_max_mm focus_distance_mm "
        "object_depth_mm fov_deg width_px velocity_range_px_per_ms"
    ).split():
        assert key in out and math.isfinite(out[key])


def test_cli_solver_and_errors(capsys):
    assert main(["design", "--max-velocity", "1.4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["velocity_range_px_per_ms"] == pytest.approx(1.4)
    assert main(["design", "--max-velocity", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--max-velocity must be > 0" in err and "Traceback" not in err
    assert main(["design", "--preset", "nope"]) == 2
    assert "unknown preset" in capsys.readouterr().err
