"""Rendered PSFs (ptracer) against the analytic model: registration, r (Eq. 12), a_i (Eq. 18),
shape at the Monte Carlo noise floor, the moving-source sensor, and the CLI (issue 6).

Kept small: every render here is a few 10^5 to 10^7 particles (well under a second each)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.io import exr as exrio
from pacam_render.model.camera import prototype
from pacam_render.model.modes import MODES_WITH_PSF, capture_camera
from pacam_render.psf.analytic import design_psf, pillbox_psf
from pacam_render.psf_render import render as prd
from pacam_render.psf_render.result import source_blur_l1
from pacam_render.psf_render.spec import PSFSpec, plan_render
from pacam_render.render.backend import select_variant
from pacam_render.restore import metrics


@pytest.fixture(scope="module")
def renderer():
    select_variant()
    return prd.PSFRenderer()


def _pair(renderer, cam, mode, s, **kw):
    a = renderer.render(cam, PSFSpec(mode, s, seed=1, **kw))
    b = renderer.render(cam, PSFSpec(mode, s, seed=2, **kw))
    return a, b, 0.5 * (a.kernel + b.kernel), metrics.rel_l1(a.kernel, b.kernel) / 2


# ------------------------------------------------------------------------------------------
# registration, r and a_i
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("depth", [500.0, 3000.0])  # both sides of the focal plane (751.5 mm)
def test_registration_and_trajectory(renderer, depth):
    cam = prototype().with_(object_depth_mm=depth)
    s = 0.6 * cam.velocity_range_px_per_ms
    a, b, mean, floor = _pair(renderer, cam, "coded", s)
    k = design_psf(cam, "coded", s)
    assert a.kernel.shape == k.shape and a.model is not None
    assert abs(a.kernel.sum() - 1.0) < 1e-12
    # the same kernel pixel is the same image position: centroids agree
    cu, cv = metrics.kernel_centroid(mean)
    ku, kv = metrics.kernel_centroid(k)
    assert abs(cu - ku) < 0.05 and abs(cv - kv) < 0.05
    # every pattern window lands where Eq. 8 + the motion put it
    traj = 0.5 * (a.centroid_u_px + b.centroid_u_px)
    assert np.abs(traj - a.model_u_px).max() < 0.05
    assert np.allclose(a.mass, 1 / 16, rtol=0.01)
    # a_i (Eq. 18, sign included: < 0 in front of the focal plane) within 1 %
    a_fit = metrics.fit_acceleration(a.t_mid_ms, traj)
    assert a_fit == pytest.approx(cam.a_i_px_per_ms2, rel=0.01)
    assert np.sign(a_fit) == (-1 if depth < cam.focus_distance_mm else 1)
    # shape at the noise floor of two seeds
    assert metrics.rel_l1(mean, k) < 1.3 * floor
    assert floor < 0.01


def test_crop_of_the_prototype_film_matches_the_window_film(renderer):
    """The crop of the 1280x960 film (the brief's set-up) and the kernel-sized film agree."""
    cam = prototype()
    s = 0.5
    crop = renderer.render(cam, PSFSpec("coded", s, spp=1, seed=4, film="crop"))
    assert crop.film["crop"]["width"] == crop.kernel.shape[1]
    # the kernel's centre pixel is a film pixel whose centre is the t = 0 image
    u0 = 640 - cam.beta_px_per_mm * (cam.R_max_mm - cam.R_mm)
    assert crop.film["kernel_origin_on_film_px"][0] == math.floor(u0) + 0.5
    assert crop.film["crop"]["offset_x"] + crop.kernel.shape[1] // 2 == math.floor(u0)
    assert crop.film["crop"]["offset_y"] + crop.kernel.shape[0] // 2 == 480
    win = renderer.render(cam, PSFSpec("coded", s, seed=5, spp=512))
    k = design_psf(cam, "coded", s)
    noise = metrics.rel_l1(crop.kernel, k) + metrics.rel_l1(win.kernel, k)
    assert metrics.rel_l1(crop.kernel, win.kernel) < 1.2 * noise
    assert np.allclose(
        metrics.kernel_centroid(crop.kernel), metrics.kernel_centroid(win.kernel), atol=0.03
    )


@pytest.mark.parametrize("mode", ["coded", "levin"])
def test_pinhole_origin_registration(renderer, mode):
    """origin='pinhole' (how deconvolve registers captures) shifts both kernels alike."""
    cam = prototype()
    r = renderer.render(cam, PSFSpec(mode, 0.3, origin="pinhole", spp=64))
    k = design_psf(cam, mode, 0.3, origin="pinhole")
    assert r.kernel.shape == k.shape
    assert np.allclose(metrics.kernel_centroid(r.kernel), metrics.kernel_centroid(k), atol=0.05)
    pin, t0 = (design_psf(cam, mode, 0.3, size=101, origin=o) for o in ("pinhole", "t0"))
    shift = metrics.kernel_centroid(pin)[0] - metrics.kernel_centroid(t0)[0]  # a_i T^2 / 4 px apart
    assert shift == pytest.approx(-cam.a_i_px_per_ms2 * cam.T_ms**2 / 4, abs=0.05)
    if mode == "coded":  # levin's in-focus line: pixel centroids are quantised near the vertex
        assert np.abs(r.centroid_u_px - r.model_u_px).max() < 0.1


def test_static_disc_radius_is_eq12(renderer):
    cam = prototype().with_(object_depth_mm=1000.0)  # behind the focal plane, r ~ 1 px
    shape = (15, 15)
    a, b, mean, floor = _pair(renderer, cam, "normal", 0.0, size=shape, per_window=False)
    r = metrics.fit_disc_radius(mean, cam.r_px)
    assert r == pytest.approx(cam.r_px, rel=0.01)
    assert metrics.rel_l1(mean, pillbox_psf(cam.r_px, size=shape)) < 1.3 * floor + 2e-3
    # the source's own size is negligible (second order in its radius)
    assert source_blur_l1(cam.r_px, prd.DEFAULT_SOURCE_RADIUS_PX) < 5e-4
    assert source_blur_l1(cam.r_px, 0.25) > 0.01  # psf_scene's default would show


@pytest.mark.parametrize("mode", ["levin", "normal", "flutter", "coded_continuous"])
def test_other_modes_match_their_analytic_psf(renderer, mode):
    cam = prototype()
    a, b, mean, floor = _pair(renderer, cam, mode, 0.4)
    assert metrics.rel_l1(mean, design_psf(cam, mode, 0.4)) < 1.3 * floor + 2e-3
    if mode == "flutter":  # closed chops are skipped: no light, no centroid
        assert np.isnan(a.centroid_u_px[~(a.mass > 0)]).all() and (a.mass == 0).any()
    if mode in ("levin", "coded_continuous"):
        assert a.fitted_a_i == pytest.approx(cam.a_i_px_per_ms2, rel=0.01)


def test_same_seed_is_bit_identical(renderer):
    cam = prototype()
    a = renderer.render(cam, PSFSpec("coded", 0.3, seed=7, spp=16))
    b = renderer.render(cam, PSFSpec("coded", 0.3, seed=7, spp=16))
    c = renderer.render(cam, PSFSpec("coded", 0.3, seed=8, spp=16))
    assert np.array_equal(a.kernel, b.kernel)  # one Dr.Jit thread: deterministic atomics
    assert not np.array_equal(a.kernel, c.kernel)


# ------------------------------------------------------------------------------------------
# the moving-scene sensor, exactly
# ------------------------------------------------------------------------------------------
def test_scene_velocity_moves_rays_and_connections(renderer):
    import drjit as dr
    import mitsuba as mi

    cam = prototype()
    renderer.render(cam, PSFSpec("coded", 0.0, spp=1))  # loads a scene
    scene, _ = next(iter(renderer._scenes.values()))
    sensor = scene.sensors()[0]
    v = (0.3, -0.2, 0.0)
    n = 5
    time_ = mi.Float(np.linspace(1.0, 44.0, n).astype(np.float32))
    u = mi.Point2f(mi.Float(np.full(n, 0.3, np.float32)), mi.Float(np.full(n, 0.6, np.float32)))
    sensor.set_scene_velocity((0.0, 0.0, 0.0))
    r0, _ = sensor.sample_ray(time_, mi.Float(0.5), u, u)
    sensor.set_scene_velocity(v)
    r1, _ = sensor.sample_ray(time_, mi.Float(0.5), u, u)
    tau = np.array(r1.time) - 22.5
    shift = np.array(r1.o) - np.array(r0.o)  # (3, n)
    assert np.allclose(shift, -np.outer(v, tau), atol=1e-4)
    assert np.allclose(np.array(r1.d), np.array(r0.d))
    # particle tracing: a point seen at time t lands where the moved point images
    it = dr.zeros(mi.Interaction3f, n)
    it.p = mi.Point3f(0.0, 0.0, 500.0)
    it.time = time_
    ds1, _ = sensor.sample_direction(it, u)
    sensor.set_scene_velocity((0.0, 0.0, 0.0))
    moved = dr.zeros(mi.Interaction3f, n)
    moved.p = mi.Point3f(mi.Float(v[0] * tau), mi.Float(v[1] * tau), mi.Float(np.full(n, 500.0)))
    moved.time = time_
    ds2, _ = sensor.sample_direction(moved, u)
    assert np.allclose(np.array(ds1.uv), np.array(ds2.uv), atol=1e-3)
    with pytest.raises(ParameterError, match="3 components"):
        sensor.set_scene_velocity((1.0, 2.0))


# ------------------------------------------------------------------------------------------
# validation grid (quick) and the CLI
# ------------------------------------------------------------------------------------------
def test_validate_psf_quick(tmp_path, capsys):
    out = tmp_path / "v"
    assert main(["validate-psf", "--quick", "--quiet", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "validate-psf (quick)" in printed
    rows = list(csv.DictReader((out / "validate_psf.csv").open()))
    assert len(rows) == 18
    for r in rows:
        assert r["r_pass"] == "True" and r["a_i_pass"] == "True" and r["l1_pass"] == "True", r
        assert abs(float(r["centroid_du_px"])) < 0.05 and abs(float(r["centroid_dv_px"])) < 0.05
        assert abs(float(r["r_err_pct"])) < 1.0
        if float(r["a_i_model"]) != 0.0:
            assert abs(float(r["a_i_err_pct"])) < 1.0
            assert float(r["l1_model_eq14_vs_discrete"]) > 0.02  # Eq. 14 is not 16 patterns
    assert {r["side"] for r in rows} == {"near", "far"}
    md = (out / "validate_psf.md").read_text()
    assert "Eq. 14 (continuous) against 16 patterns" in md
    for name in ("validate_psf_r_ai.png", "validate_psf_l1.png", "validate_psf_examples.png"):
        assert (out / name).stat().st_size > 1000
    assert main(["validate-psf", "--quick", "--quiet", "--out", str(out)]) == 2  # no overwrite
    assert "already holds results" in capsys.readouterr().err


def test_cli_psf_render(tmp_path):
    out = tmp_path / "p"
    args = ["psf", "--depth", "500", "--velocity", "0.5", "--render", "--quiet"]
    assert main([*args, "--spp", "32", "--seed", "3", "--out", str(out)]) == 0
    k = exrio.read_layer(out / "psf_analytic.exr", "psf")
    layers = exrio.read_exr(out / "psf_rendered.exr")
    assert list(layers) == ["psf"]  # one single-channel layer
    r = layers["psf"]
    assert r.shape == k.shape and r.dtype == np.float32
    assert abs(float(r.sum(dtype=np.float64)) - 1) < 1e-5
    assert metrics.rel_l1(r, k) < 0.05
    meta = json.loads((out / "psf.json").read_text())
    rend = meta["rendered"]
    assert rend["spp"] == 32 and rend["seed"] == 3 and rend["run_time_s"] > 0
    assert len(rend["centroid_trajectory"]) == 16
    assert rend["fitted_a_i_px_per_ms2"] == pytest.approx(meta["a_i_px_per_ms2"], rel=0.01)
    assert rend["integrator"].startswith("ptracer") and rend["rfilter"] == "box"


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--render", "--spp", "0"], "spp"),
        (["--render", "--spp", "-3"], "spp"),
        (["--render", "--seed", "-1"], "seed"),
        (["--spp", "16"], "need --render"),
        (["--render", "--size", "1001"], "must fit the 1280x960 film"),
        (["--render", "--depth", "5"], "--depth must be >= 100 mm"),
        (["--render", "--depth", "-5"], "--depth must be > 0"),
        (["--render", "--depth", "0"], "--depth must be > 0"),
    ],
)
def test_cli_psf_render_errors(tmp_path, capsys, extra, message):
    out = tmp_path / "e"
    args = ["psf", "--depth", "500", "--velocity", "0.5", "--quiet", "--out", str(out), *extra]
    assert main(args) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()  # nothing written


def test_in_focus_depth_is_a_clear_error(tmp_path, capsys):
    zf = prototype().focus_distance_mm
    out = tmp_path / "f"
    assert main(["psf", "--depth", repr(zf), "--velocity", "0", "--render", "--out", str(out)]) == 2
    assert "beta = 0" in capsys.readouterr().err
    with pytest.raises(ParameterError, match="spp"):
        plan_render(prototype(), PSFSpec(spp=2.5))
    with pytest.raises(ParameterError, match="integrator"):
        plan_render(prototype(), PSFSpec(integrator="bdpt"))
    with pytest.raises(ParameterError, match="mode"):
        plan_render(prototype(), PSFSpec("bogus"))


@pytest.mark.parametrize("mode", ["coded", "normal", "flutter"])
def test_a_psf_rendered_with_diffraction_matches_the_diffracted_model(renderer, mode):
    """The prototype's PSF at its full pixel scale (F9.85: lambda N = 0.93 / 0.84 / 0.71 px in
    R, G, B) with the opening's diffraction in the particles: at the Monte Carlo floor of two
    seeds against each channel's exact defocused kernel, mixed by luminance (issue 45; the
    exact kernel itself is checked against an independent Fresnel computation in
    tests/render/test_exact_defocus.py); the geometric kernel, and the geometric kernel
    convolved with the Airy pattern (the box counted twice, with_diffraction), are several
    floors away."""
    import mitsuba as mi

    from pacam_render.psf.diffraction import with_diffraction
    from pacam_render.psf_render.diffraction import LUMINANCE_RGB, diffracted_model

    cam = capture_camera(prototype(), mode)
    s = 0.4
    a, b, mean, floor = _pair(renderer, cam, mode, s, diffraction=True)
    geometric = design_psf(cam, mode, s)
    h, w = geometric.shape

    def build(c, f, fine):
        return design_psf(c, mode, s * f, fine)

    n = 1 if "mono" in mi.variant() else 3
    model = diffracted_model(build, cam, mode, (h, w), n, None, s, "t0")
    assert np.allclose(a.model, model)
    assert metrics.rel_l1(mean, model) < 1.3 * floor + 2e-3
    assert metrics.rel_l1(mean, geometric) > 5 * floor
    waves = (611.0, 549.0, 464.0) if n == 3 else (550.0,)
    weights = LUMINANCE_RGB if n == 3 else (1.0,)
    twice = sum(q * with_diffraction(geometric, cam, mode, wl, size=(h, w))
                for q, wl in zip(weights, waves))  # fmt: skip
    assert metrics.rel_l1(mean, twice) > 2 * floor
    assert floor < 0.02


def test_diffraction_in_a_psf_render_needs_an_opening():
    from pacam_render.psf_render.diffraction import sensor_params

    with pytest.raises(ParameterError, match="pinhole, it has no opening"):
        sensor_params(prototype(), "reference", 3)
    with pytest.raises(ParameterError, match="pixel_pitch_mm must be > 0"):
        plan_render(prototype(), PSFSpec("coded", 0.0, diffraction=True, pixel_pitch_mm=-1.0))


@pytest.mark.parametrize("mode", MODES_WITH_PSF)
def test_every_mode_of_the_table_renders_its_analytic_psf(renderer, mode):
    """The camera a capture of each mode uses (model.modes.capture_camera), ray-traced as a
    point source, agrees with the analytic kernel that the same table names, at the Monte
    Carlo floor of two seeds."""
    cam = capture_camera(prototype(), mode)
    s = 0.4
    a, b, mean, floor = _pair(renderer, cam, mode, s)
    assert metrics.rel_l1(mean, design_psf(cam, mode, s)) < 1.3 * floor + 2e-3
    assert a.seconds > 0 and floor < 0.02


def test_a_bitmap_schedule_renders_its_own_kernel_at_the_monte_carlo_floor():
    """Square openings on the LCoS, 8 along the parabola: the rendered PSF (ptracer, two
    seeds) matches the exact bitmap kernel at the noise floor, and a_i the fit to its own
    centroids; discs of the same area at the same centres would be a visibly other kernel."""
    from pacam_render.experiments import validate_psf as V
    from pacam_render.model.camera import preset
    from pacam_render.model.masks import MaskStack, square_masks
    from pacam_render.psf.analytic import design_psf

    proto = preset("prototype")
    centres = proto.pattern_centres_xy_mm()[::2]
    stack = MaskStack(
        square_masks(centres, 0.5 * np.sqrt(np.pi) * proto.R_mm)
    )  # a square of the disc's area
    cam = proto.with_(pattern_masks=stack, n_patterns=8, R_mm=stack.equivalent_radius_mm())
    grid = V.Grid("bitmap", (500.0,), (cam.F_number,), (0.0, 1.0), 1 << 15, design=cam)
    rows = V.pair_task((500.0, cam.F_number, grid))
    for row, _ in rows:
        assert row["l1_pass"] and row["a_i_pass"] and row["r_pass"], row
        assert row["l1_ratio"] < 2.0
    discs = design_psf(cam.with_(pattern_masks=None, pattern_centres_mm=tuple(map(tuple, centres))),
                       "coded", 0.0, size=rows[0][1]["discrete"].shape)  # fmt: skip
    assert metrics.rel_l1(discs, rows[0][1]["discrete"]) > 5 * rows[0][0]["l1_noise_floor"]
