"""Relative illumination (natural vignetting) of the ``programmable_aperture`` sensor.

References: cos^4 of the chief ray's field angle computed here in numpy; the exact thin-lens
integral (a numerical quadrature over the pupil, against the closed form); Mitsuba's
``thinlens`` for ``off``; a known piecewise-linear curve for the user curves; and the other
integrator (the path tracer uses ``sample_ray``, the particle tracer ``sample_direction``).

Uniform-radiance scenes: a constant environment (a camera ray that meets nothing returns its
radiance, so a path render is the factor map with only the pixel-position noise), and a large
diffuse emitter plane at the focus distance that fills the frame (for the particle tracer).
"""

from __future__ import annotations

import json
import math

import mitsuba as mi
import numpy as np
import pytest

from pacam_render import render as ac
from pacam_render.errors import ParameterError
from pacam_render.model.illumination import (
    TABLE_SIZE,
    film_tangents,
    parse_relative_illumination,
    read_curve,
    relative_illumination_map,
    thin_lens_relative_illumination,
)
from pacam_render.render.backend import select_variant

W, H, FOV = 64, 48, 46.0  # the prototype's field of view: corners at 27.95 deg
F_PX = 0.5 * W / math.tan(math.radians(FOV) / 2)
L = 2.0  # the scenes' radiance


def film(w=W, h=H, **crop):
    return {
        "type": "hdrfilm",
        "width": w,
        "height": h,
        "rfilter": {"type": "box"},
        "pixel_format": "luminance",
        "component_format": "float32",
        **crop,
    }


def sensor(ri="off", fov=FOV, f=None, **kw):
    return ac.sensor_dict(
        fov=fov,
        focus_distance=1000.0,
        lens_radius=5.0,
        film=f or film(),
        shutter_open=0.0,
        shutter_close=10.0,
        relative_illumination=ri,
        **kw,
    )


def env_scene(sens: dict, integrator="path"):
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator},
            "sensor": sens,
            "env": {"type": "constant", "radiance": {"type": "rgb", "value": L}},
        }
    )


def wall_scene(sens: dict, integrator: str):
    """A diffuse emitter of radiance L at the focus distance, filling the frame."""
    T = mi.ScalarTransform4f
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator, "max_depth": 2},
            "sensor": sens,
            "wall": {
                "type": "rectangle",
                "to_world": T().translate([0, 0, 1000])
                @ T().rotate([1, 0, 0], 180)
                @ T().scale(700),
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": L}},
            },
        }
    )


def render(scene, spp, seed=0):
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)
    return img[..., 0] if img.ndim == 3 else img


def cos4_centres(w=W, h=H, fov=FOV):
    """cos^4 of each pixel centre's field angle."""
    t = film_tangents(w, h, fov)
    return (1.0 + t * t) ** -2


@pytest.fixture
def variant():
    select_variant()
    ac.register()


def write(tmp_path, name: str, text: str):
    p = tmp_path / name
    p.write_text(text)
    return p


# ------------------------------------------------------------------------------------------
# numpy: the factor, the exact thin-lens integral, the map, the curve files
# ------------------------------------------------------------------------------------------


def irradiance(tan_theta: float, f_number: float, centre=0.0, radius=1.0, n=600) -> float:
    """(1/d^2) integral of cos^4 over a disc pupil (mean over its area), numerically: the
    pupil of F-number ``f_number`` scaled by ``radius``, its centre at ``centre`` pupil radii
    along x, the film point at tan theta along x."""
    rho = 0.5 / f_number
    r = (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi
    R, P = np.meshgrid(r, phi)
    ax, ay = (centre + radius * R * np.cos(P)) * rho, radius * R * np.sin(P) * rho
    return float(np.sum(R / (1 + (tan_theta + ax) ** 2 + ay**2) ** 2) / np.sum(R))


def quadrature(tan_theta: float, f_number: float) -> float:
    """E(h) / E(0) of a centred disc pupil."""
    return irradiance(tan_theta, f_number) / irradiance(0.0, f_number)


@pytest.mark.parametrize("N", [0.7, 2.8, 9.85, 16.0])
@pytest.mark.parametrize("deg", [10.0, 27.9, 60.0])
def test_thin_lens_closed_form_matches_the_pupil_integral(N, deg):
    t = math.tan(math.radians(deg))
    assert float(thin_lens_relative_illumination(t, N)) == pytest.approx(quadrature(t, N), rel=1e-6)


def test_thin_lens_departure_from_cos4_as_documented():
    """The figures quoted in model/illumination.py: the exact centred-disc integral over cos^4
    of the chief ray at the frame's corner (27.9 deg) and the window's (18.4 deg)."""
    quoted = {(2.8, 27.9): 2.29, (9.85, 27.9): 0.19, (16.0, 27.9): 0.07}
    quoted.update({(2.8, 18.4): 1.14, (9.85, 18.4): 0.09, (16.0, 18.4): 0.04})
    for (N, deg), pct in quoted.items():
        th = math.radians(deg)
        ratio = float(thin_lens_relative_illumination(math.tan(th), N)) / math.cos(th) ** 4
        assert 100 * (ratio - 1) == pytest.approx(pct, abs=0.005), (N, deg)
    # and it tends to cos^4 as the pupil shrinks; finite (no NaN) to 90 deg
    t = np.tan(np.radians([0.0, 30.0, 89.9, 89.999]))
    slow = thin_lens_relative_illumination(t, 1e4)
    assert np.allclose(slow, (1 + t * t) ** -2, rtol=1e-6)
    assert np.all(np.isfinite(thin_lens_relative_illumination(t, 2.8)))


def test_moving_opening_departure_as_documented():
    """model/illumination.py's figures for the parabolic schedule's 145.5 px opening on the
    F2.8 LCoS at the middle of a side edge of the 1280x960 frame (23 deg): the two ends of
    the parabola, and the average over the exposure (the centre at (1 - rr)(1 - 2 tau^2) for
    tau uniform in [-1, 1], rr = 145.5 / 512), each over its own value on the axis."""
    t = math.tan(math.radians(23.0))  # the edge's middle: 640 px from the axis, f_px = 640 / tan 23
    rr = 145.5 / 512
    cos4 = (1 + t * t) ** -2

    def ratio(centres, tan):
        num = np.mean([irradiance(tan, 2.8, c, rr, 200) for c in centres])
        return num / np.mean([irradiance(0.0, 2.8, c, rr, 200) for c in centres]) / cos4 - 1

    ends = [ratio([c], t) for c in (1 - rr, -(1 - rr))]
    assert 100 * np.array(ends) == pytest.approx([-15.35, 21.57], abs=0.05)
    tau = (np.arange(64) + 0.5) / 64 * 2 - 1
    centres = (1 - rr) * (1 - 2 * tau**2)
    mean = [ratio(centres, s * t) for s in (1, -1)]
    assert 100 * np.array(mean) == pytest.approx([-4.57, 7.60], abs=0.05)


def test_cos4_map_is_the_pixel_average_of_cos4():
    m = relative_illumination_map("cos4", 1280, 960, 46.0)
    assert m.shape == (960, 1280)
    assert m[0, 0] == pytest.approx(
        math.cos(math.atan(math.hypot(639.5, 479.5) / (640 / math.tan(math.radians(23))))) ** 4,
        rel=1e-5,
    )
    assert m[0, 0] == pytest.approx(0.609, abs=5e-4)  # 27.9 deg: PHYSICS.md's 0.61
    assert np.array_equal(m, m[::-1, ::-1])  # symmetric about the axis
    fine = relative_illumination_map("cos4", 1280, 960, 46.0, sub=16)
    assert np.abs(fine - m).max() < 1e-6
    assert relative_illumination_map("off", 1280, 960, 46.0) is None
    crop = relative_illumination_map("cos4", 1280, 960, 46.0, crop=(200, 560, 400, 160))
    assert np.array_equal(crop, m[560:720, 200:600])


def test_settings_and_their_errors():
    assert parse_relative_illumination(None).kind == "off"
    assert parse_relative_illumination(" COS4 ").kind == "cos4"
    for bad in ("cos5", "vignette", "curve.txt", ""):
        with pytest.raises(ParameterError, match="relative_illumination must be off, cos4"):
            parse_relative_illumination(bad)


def test_curve_files_read(tmp_path):
    csv = write(
        tmp_path,
        "lens.csv",
        "# a lens, in percent\nheight_mm, relative_illumination\n0, 100\n2.0, 90\n\n4.2, 70\n",
    )
    abscissa, x, y = read_curve(csv)
    assert abscissa == "height_mm" and x.tolist() == [0, 2.0, 4.2]
    assert y.tolist() == pytest.approx([1.0, 0.9, 0.7])  # divided by the centre's value
    js = write(
        tmp_path,
        "lens.json",
        json.dumps(
            {"field_deg": [0, 10, 30], "relative_illumination": [1, 0.9, 0.6], "comment": "x"}
        ),
    )
    ri = parse_relative_illumination(str(js))
    assert ri.kind == "curve" and ri.abscissa == "field_deg"
    assert ri.factor(math.tan(math.radians(20.0)))[()] == pytest.approx(0.75, abs=1e-3)
    # a height_mm curve needs the pixel pitch, and says so
    with pytest.raises(ParameterError, match="needs the pixel pitch"):
        parse_relative_illumination(str(csv)).factor(0.1, focal_px=100.0)


@pytest.mark.parametrize(
    "name, text, problem",
    [
        ("a.csv", "", "empty"),
        ("a.csv", "height_cm,relative_illumination\n0,1\n1,0.9\n", "line 1: the header"),
        ("a.csv", "height_px,relative_illumination\n0,1\n1;0.9\n", "line 3: expected two numbers"),
        ("a.csv", "height_px,relative_illumination\n0,1\n", "at least two points"),
        ("a.csv", "height_px,relative_illumination\n1,1\n2,0.9\n", "must start at 0"),
        ("a.csv", "height_px,relative_illumination\n0,1\n5,0.9\n5,0.8\n", "increase strictly"),
        ("a.csv", "height_px,relative_illumination\n0,1\n5,nan\n", "finite"),
        ("a.csv", "height_px,relative_illumination\n0,1\n5,-0.1\n", ">= 0"),
        ("a.csv", "height_px,relative_illumination\n0,0\n5,0.5\n", "must be > 0"),
        ("a.csv", "field_deg,relative_illumination\n0,1\n90,0\n", "< 90"),
        ("a.json", "{not json", "not valid JSON"),
        ("a.json", "[1, 2]", "expected a JSON object"),
        ("a.json", '{"height_px": [0, 1]}', "expected one of"),
        ("a.json", '{"height_px": [0, 1], "relative_illumination": [1]}', "pair up"),
        ("a.json", '{"height_px": [0, "x"], "relative_illumination": [1, 1]}', "list of numbers"),
    ],
)
def test_bad_curve_files_name_the_file_and_the_problem(tmp_path, name, text, problem):
    path = write(tmp_path, name, text)
    with pytest.raises(ParameterError) as err:
        parse_relative_illumination(str(path))
    assert str(path) in str(err.value) and problem in str(err.value)


def test_missing_curve_file(tmp_path):
    with pytest.raises(ParameterError, match="no such file"):
        parse_relative_illumination(str(tmp_path / "missing.csv"))


def test_a_curve_short_of_the_corner_is_refused(tmp_path):
    short = write(tmp_path, "s.csv", "height_px,relative_illumination\n0,1\n30,0.8\n")
    with pytest.raises(ParameterError, match="short of the film's farthest corner at 40.00 px"):
        relative_illumination_map(str(short), W, H, FOV)


# ------------------------------------------------------------------------------------------
# the plugin: sample_ray and sample_direction
# ------------------------------------------------------------------------------------------


def _chief_tan(uv):
    """tan theta_c of film positions uv in [0, 1]^2 of the W x H film."""
    u = (np.asarray(uv[0]) - 0.5) * W / F_PX
    v = (np.asarray(uv[1]) - 0.5) * H / F_PX
    return np.hypot(u, v)


@pytest.mark.render
def test_sample_ray_weight_is_cos4_of_the_chief_ray(variant):
    cos4 = mi.load_dict(sensor("cos4"))
    off = mi.load_dict(sensor("off"))
    rng = np.random.default_rng(1)
    n = 2000
    uv = rng.random((2, n))
    args = (
        mi.Float(rng.random(n) * 10),
        mi.Float(rng.random(n)),
        mi.Point2f(*uv),
        mi.Point2f(*rng.random((2, n))),
    )
    for method in ("sample_ray", "sample_ray_differential"):
        r1, w1 = getattr(cos4, method)(*args)
        r0, w0 = getattr(off, method)(*args)
        assert np.array_equal(np.array(r1.d), np.array(r0.d))  # the same rays
        t = _chief_tan(uv)
        ratio = np.array(w1)[0] / np.array(w0)[0]
        assert np.allclose(ratio, (1 + t * t) ** -2, rtol=2e-6, atol=1e-7)


@pytest.mark.render
def test_sample_direction_weight_is_cos4_of_its_film_position(variant):
    cos4 = mi.load_dict(sensor("cos4"))
    off = mi.load_dict(sensor("off"))
    rng = np.random.default_rng(2)
    n = 2000
    it = mi.Interaction3f()
    it.p = mi.Point3f(
        rng.uniform(-500, 500, n), rng.uniform(-400, 400, n), rng.uniform(300, 3000, n)
    )
    it.time = mi.Float(rng.random(n) * 10)
    s = mi.Point2f(*rng.random((2, n)))
    d1, w1 = cos4.sample_direction(it, s)
    d0, w0 = off.sample_direction(it, s)
    w1, w0 = np.array(w1)[0], np.array(w0)[0]
    hit = w0 > 0
    assert hit.sum() > 200 and np.array_equal(w1 > 0, hit)
    uv = np.array(d0.uv)[:, hit] / np.array([[W], [H]])
    t = _chief_tan(uv)
    assert np.allclose(w1[hit] / w0[hit], (1 + t * t) ** -2, rtol=1e-5)


# ------------------------------------------------------------------------------------------
# renders of a uniform-radiance scene (the must-show)
# ------------------------------------------------------------------------------------------


@pytest.mark.render
def test_uniform_scene_with_cos4_follows_cos4_of_the_field_angle(variant):
    img = render(env_scene(sensor("cos4")), spp=256)
    centre = img[H // 2 - 1 : H // 2 + 1, W // 2 - 1 : W // 2 + 1].mean()
    ratio = img / centre
    ref = cos4_centres()
    ref = ref / ref[H // 2 - 1 : H // 2 + 1, W // 2 - 1 : W // 2 + 1].mean()
    assert np.abs(ratio / ref - 1).max() < 0.02  # the must-show's 2 %
    assert np.abs(ratio / ref - 1).max() < 2e-3  # in fact: only the in-pixel position noise
    corner = math.atan(math.hypot(W / 2 - 0.5, H / 2 - 0.5) / F_PX)  # 27.5 deg
    assert ratio[0, 0] == pytest.approx(math.cos(corner) ** 4 / ref.max(), abs=2e-3)
    # and it is the recorded map, which flat-fields it back to L
    m = relative_illumination_map("cos4", W, H, FOV)
    assert np.abs(img / (L * m) - 1).max() < 2e-3


@pytest.mark.render
def test_off_is_flat_and_equals_thinlens(variant):
    ours = render(env_scene(sensor("off")), spp=16, seed=5)
    default = render(env_scene(sensor()), spp=16, seed=5)
    f = film()
    thin = dict(type="thinlens", aperture_radius=5.0, fov=FOV, focus_distance=1000.0, film=f)
    ref = render(env_scene({**thin, "shutter_open": 0.0, "shutter_close": 10.0}), spp=16, seed=5)
    assert np.all(ours == L) and np.array_equal(ours, ref) and np.array_equal(ours, default)
    # a scene with texture and depth too: the same samples give the same image
    a = render(wall_scene(sensor("off"), "path"), spp=16, seed=3)
    b = render(wall_scene({**thin, "shutter_open": 0.0, "shutter_close": 10.0}, "path"), 16, 3)
    assert np.abs(a - b).max() < 1e-5


@pytest.mark.render
@pytest.mark.parametrize("integrator", ["path", "ptracer"])
def test_field_angle_near_90_degrees_gives_no_nan(variant, integrator):
    f = film(32, 24)
    fov = 179.0  # the corners at 89.6 deg: cos^4 ~ 2e-9
    img = render(wall_scene(sensor("cos4", fov=fov, f=f), integrator), spp=16)
    assert np.all(np.isfinite(img)) and img.min() >= 0
    cam = mi.load_dict(sensor("cos4", fov=fov, f=f))
    corner = mi.Point2f([0.0, 1.0, 0.5], [0.0, 1.0, 0.5])
    _, w = cam.sample_ray(
        mi.Float([5.0] * 3), mi.Float([0.5] * 3), corner, mi.Point2f([0.5] * 3, [0.5] * 3)
    )
    w = np.array(w)[0]
    t = math.hypot(16, 12) / (16 / math.tan(math.radians(fov / 2)))
    assert np.all(np.isfinite(w)) and w[0] == pytest.approx((1 + t * t) ** -2, rel=1e-3)
    assert w[2] == pytest.approx(1.0)


@pytest.mark.render
def test_user_curves_reproduce_a_known_curve(variant, tmp_path):
    # a piecewise-linear curve in px, and the prototype's cos^4 as a field_deg curve
    px = np.array([0.0, 10.0, 25.0, 40.1])
    vals = np.array([1.0, 0.97, 0.8, 0.5])
    rows = "\n".join(f"{a},{b}" for a, b in zip(px, vals))
    csv = write(tmp_path, "px.csv", "height_px,relative_illumination\n" + rows + "\n")
    img = render(env_scene(sensor(str(csv))), spp=256) / L
    sub = film_tangents(W, H, FOV, sub=8) * F_PX  # px from the axis, 8x8 points per pixel
    known = np.interp(sub, px, vals).mean(axis=-1)
    assert np.abs(img - known).max() < 2e-3
    assert np.abs(img - relative_illumination_map(str(csv), W, H, FOV)).max() < 2e-3
    deg = np.linspace(0.0, 30.0, 61)
    js = write(
        tmp_path,
        "cos4.json",
        json.dumps(
            {
                "field_deg": deg.tolist(),
                "relative_illumination": (np.cos(np.radians(deg)) ** 4).tolist(),
            }
        ),
    )
    a = render(env_scene(sensor(str(js))), spp=64, seed=1)
    b = render(env_scene(sensor("cos4")), spp=64, seed=1)
    assert np.abs(a / b - 1).max() < 1e-3  # same samples; 0.5 deg knots: interpolation only
    # height_mm with the film's pixel pitch: the same curve as px
    mm = write(
        tmp_path,
        "mm.csv",
        "height_mm,relative_illumination\n"
        + "\n".join(f"{a * 0.01},{b}" for a, b in zip(px, vals))
        + "\n",
    )
    c = render(env_scene(sensor(str(mm), pixel_pitch=0.01)), spp=256) / L
    assert np.abs(c - img).max() < 1e-5
    assert TABLE_SIZE >= 1024


@pytest.mark.render
def test_bad_settings_are_refused_before_loading(variant, tmp_path):
    with pytest.raises(ParameterError, match="relative_illumination must be off, cos4"):
        sensor("cos3")
    short = write(tmp_path, "short.csv", "height_px,relative_illumination\n0,1\n30,0.8\n")
    with pytest.raises(ParameterError, match="short of the film's farthest corner"):
        sensor(str(short))
    mm = write(tmp_path, "mm.csv", "height_mm,relative_illumination\n0,1\n3,0.8\n")
    with pytest.raises(ParameterError, match="needs the pixel pitch"):
        sensor(str(mm))
    with pytest.raises(ParameterError, match="pixel_pitch must be > 0"):
        sensor("cos4", pixel_pitch=-1.0)


# ------------------------------------------------------------------------------------------
# path and particle tracing agree (energy and importance)
# ------------------------------------------------------------------------------------------


@pytest.mark.render
def test_ptracer_and_path_agree_with_cos4(variant):
    sens = sensor("cos4")
    path = render(wall_scene(sens, "path"), spp=64)
    m = relative_illumination_map("cos4", W, H, FOV)
    assert np.abs(path / (L * m) - 1).max() < 5e-3  # the wall fills the frame
    a = render(wall_scene(sens, "ptracer"), spp=512, seed=1)
    b = render(wall_scene(sens, "ptracer"), spp=512, seed=2)
    noise = np.abs(a - b).mean() / path.mean()  # sqrt(2) x one image's noise
    assert noise > 0.02  # the comparisons below are meaningful
    assert np.abs(a - path).mean() / path.mean() < 0.85 * noise  # expected 0.71
    pt = 0.5 * (a + b)
    assert pt.mean() == pytest.approx(path.mean(), rel=0.005)
    # ring by ring from the axis to the corners: no trend left with the field angle
    t = film_tangents(W, H, FOV)
    edges = np.quantile(t, [0, 0.25, 0.5, 0.75, 1.0])
    for lo, hi in zip(edges[:-1], edges[1:]):
        ring = (t >= lo) & (t <= hi)
        assert pt[ring].mean() / path[ring].mean() == pytest.approx(1.0, abs=0.01)
    # the same particles with off: the ratio is the map, splat by splat
    off = render(wall_scene(sensor("off"), "ptracer"), spp=512, seed=1)
    assert np.abs(a / off / m - 1).max() < 0.01
