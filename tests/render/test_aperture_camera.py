"""The ``programmable_aperture`` sensor against independent references.

References: Mitsuba's built-in ``thinlens`` (geometry and radiometry), the paper's Eq. 8
(image shift -beta * X_a for an aperture offset X_a) and Eqs. 2 and 18 (parabolic image
trajectory), the open-area and exposure ratios, ``schedule.pattern_index`` (float64), and the
other integrator (path tracing uses ``sample_ray``, particle tracing ``sample_direction``).

Film x and camera x: Mitsuba's camera space has +x to the image's left, so film column u
grows along local -x. A point on the optical axis images at u = W/2; an aperture offset
(X_a, Y_a) along local (+x, +y) moves its image by (-beta X_a, -beta Y_a) in (column, row).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from pacam_render import render as ac
from pacam_render.errors import ParameterError
from pacam_render.model import schedule as sch
from pacam_render.model.optics import LCOS_PITCH_MM, beta_px_per_mm, focal_length_px
from pacam_render.render.backend import select_variant
from pacam_render.render.masks import disc_masks, pixel_centres_mm


@pytest.fixture(autouse=True)
def _variant():
    select_variant()
    ac.register()


def T_():
    return mi.ScalarTransform4f()


def film(w=64, h=None, fmt="luminance"):
    return {
        "type": "hdrfilm",
        "width": w,
        "height": h or w,
        "rfilter": {"type": "box"},
        "pixel_format": fmt,
        "component_format": "float32",
    }


def psf_scene(sensor: dict, Z: float, x: float = 0.0, y: float = 0.0, r: float = 0.3):
    """A small one-sided disc emitter at depth Z facing the camera; particle tracing."""
    emitter = {
        "type": "disk",
        "to_world": T_().translate([x, y, Z]) @ T_().rotate([1, 0, 0], 180) @ T_().scale(r),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}},
    }
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "ptracer", "max_depth": 2},
            "sensor": sensor,
            "emitter": emitter,
        }
    )


def wall_scene(sensor: dict, integrator: str):
    """A diffuse checkerboard wall at 1000 mm lit by a spot light (low noise for both the
    path and the particle tracer)."""
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator, "max_depth": 3},
            "sensor": sensor,
            "wall": {
                "type": "rectangle",
                "to_world": T_().translate([0, 0, 1000])
                @ T_().rotate([1, 0, 0], 180)
                @ T_().scale(400),
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": {
                        "type": "checkerboard",
                        "to_uv": mi.ScalarTransform3f().scale(6),
                    },
                },
            },
            "light": {
                "type": "spot",
                "cutoff_angle": 35.0,
                "beam_width": 30.0,
                "to_world": T_().look_at(origin=[0, 0, 400], target=[0, 0, 1000], up=[0, 1, 0]),
                "intensity": {"type": "rgb", "value": 1e5},
            },
        }
    )


def render(scene, spp, seed=0):
    img = np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)
    return img[..., 0] if img.ndim == 3 else img


def centroid(img):
    """(u, v) centroid in film pixel coordinates (pixel centres at i + 0.5)."""
    u = np.arange(img.shape[1]) + 0.5
    v = np.arange(img.shape[0]) + 0.5
    s = img.sum()
    return float(img.sum(axis=0) @ u / s), float(img.sum(axis=1) @ v / s)


def rel_l1(a, b):
    return float(np.abs(a - b).mean() / np.abs(a).mean())


def blocks(img, k=4):
    h, w = img.shape[0] // k * k, img.shape[1] // k * k
    return img[:h, :w].reshape(h // k, k, w // k, k).mean(axis=(1, 3))


# ------------------------------------------------------------------------------------------
# 1. thinlens
# ------------------------------------------------------------------------------------------

THIN = dict(fov=35.0, focus_distance=600.0, shutter_open=0.0, shutter_close=10.0)


def tilt():
    return T_().look_at(origin=[30, -20, 0], target=[0, 0, 1000], up=[0, 1, 0])


@pytest.mark.parametrize("integrator", ["path", "ptracer"])
def test_full_opening_equals_thinlens(integrator):
    f = film(40, 32, "rgb")
    ours = ac.sensor_dict(lens_radius=25.0, film=f, to_world=tilt(), **THIN)
    ref = dict(type="thinlens", aperture_radius=25.0, film=f, to_world=tilt(), **THIN)
    a = render(wall_scene(ref, integrator), 64, seed=3)
    b = render(wall_scene(ours, integrator), 64, seed=3)
    c = render(wall_scene(ref, integrator), 64, seed=4)  # Monte Carlo noise level
    d = render(wall_scene(ours, integrator), 64, seed=4)
    noise = rel_l1(a, c)
    assert noise > 0.02  # the comparison below is meaningful
    # same samples: the same rays and weights, up to float rounding
    assert rel_l1(a, b) < 1e-4
    # independent samples: equal to Monte Carlo noise, pixel by pixel and in the mean
    assert rel_l1(a, d) < 1.2 * noise
    assert d.mean() == pytest.approx(a.mean(), rel=0.02)


def test_ray_differentials_match_thinlens():
    f = film(24, 20)
    ours = mi.load_dict(ac.sensor_dict(lens_radius=5.0, film=f, to_world=tilt(), **THIN))
    ref = mi.load_dict(dict(type="thinlens", aperture_radius=5.0, film=f, to_world=tilt(), **THIN))
    rng = np.random.default_rng(0)
    n = 1000
    args = (
        mi.Float(rng.random(n) * 10),
        mi.Float(rng.random(n)),
        mi.Point2f(rng.random(n), rng.random(n)),
        mi.Point2f(rng.random(n), rng.random(n)),
    )
    r1, w1 = ours.sample_ray_differential(*args)
    r2, w2 = ref.sample_ray_differential(*args)
    for name in ("o", "d", "d_x", "d_y"):
        x1, x2 = np.array(getattr(r1, name)), np.array(getattr(r2, name))
        assert np.allclose(x1, x2, atol=1e-5, rtol=1e-5), name
    # thinlens' generic differential re-samples the origin: the same lens point moved along
    # the differential ray by near_clip; ours keeps o_x = o_y = o, as thinlens.cpp itself does
    for name in ("o_x", "o_y"):
        x1, x2 = np.array(getattr(r1, name)), np.array(getattr(r2, name))
        assert np.allclose(x1, np.array(r1.o)) and np.allclose(x1, x2, atol=1e-3), name
    assert np.allclose(np.array(r1.maxt), np.array(r2.maxt), rtol=1e-5)
    assert bool(r1.has_differentials)
    assert np.allclose(np.array(w1), np.array(w2))
    # the plain rays too
    r3, _ = ours.sample_ray(*args)
    assert np.allclose(np.array(r3.d), np.array(r2.d), atol=1e-6)


# ------------------------------------------------------------------------------------------
# 2. Eq. 8: an offset opening shifts a defocused point's image by -beta * c
# ------------------------------------------------------------------------------------------

W = 64
FOV = 30.0
ZF = 250.0


@pytest.mark.parametrize("Z", [1000.0, 150.0])  # beyond and in front of the focal plane
@pytest.mark.parametrize("c", [(10.0, 0.0), (-10.0, 0.0), (0.0, 8.0), (-6.0, -7.0)])
def test_offset_disc_shifts_image_by_minus_beta_c(Z, c):
    beta = beta_px_per_mm(Z, ZF, FOV, W)  # +0.358 px/mm at 1000 mm, -0.318 at 150 mm
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=16.0,
        aperture_radius=6.0,
        schedule="centres",
        centres=f"{c[0]} {c[1]}",
        film=film(W),
    )
    u, v = centroid(render(psf_scene(sd, Z), 64))
    assert abs(beta * math.hypot(*c)) > 2.0  # a shift worth measuring
    assert u == pytest.approx(W / 2 - beta * c[0], abs=0.05)
    assert v == pytest.approx(W / 2 - beta * c[1], abs=0.05)


# ------------------------------------------------------------------------------------------
# 3. a bitmap of discs matches the analytic discs, in distribution
# ------------------------------------------------------------------------------------------


def test_bitmap_sampler_follows_transmittance():
    """The kernel's guided CDF search picks pixels in proportion to their grey level."""
    rng = np.random.default_rng(5)
    pitch, shape = 0.1, (24, 32)
    m = np.zeros((2,) + shape, np.float32)
    m[0, 4:20, 6:28] = 0.98 * rng.random((16, 22)) + 0.02
    m[0, 10:12, 10:12] = 0.0
    m[1, 2:5, 3:9] = 1.0
    m[1, 18:20, 25:27] = 0.25
    sensor = mi.load_dict(
        ac.sensor_dict(
            fov=FOV,
            focus_distance=ZF,
            lens_radius=2.5,
            schedule="bitmap",
            masks=m,
            mask_pitch=pitch,
            shutter_open=0.0,
            shutter_close=2.0,
            film=film(8),
        )
    )
    n = 400_000
    xc, yc = pixel_centres_mm(shape, pitch)
    for k, t in enumerate((0.5, 1.5)):
        x, y, w = sensor.sample_aperture(np.full(n, t), rng.random(n), rng.random(n))
        j = np.rint(shape[1] / 2 - 0.5 - x / pitch).astype(int)
        i = np.rint(shape[0] / 2 - 0.5 - y / pitch).astype(int)
        assert np.all(np.abs(x - xc[j]) <= pitch / 2 + 1e-5)
        assert np.all(np.abs(y - yc[i]) <= pitch / 2 + 1e-5)
        for frac in ((xc[j] - x) / pitch + 0.5, (y - yc[i]) / pitch + 0.5):  # uniform in pixel
            assert frac.mean() == pytest.approx(0.5, abs=0.005)
            assert frac.var() == pytest.approx(1 / 12, abs=0.003)
            assert np.histogram(frac, bins=10, range=(0, 1))[0].min() > 0.09 * n
        counts = np.zeros(shape)
        np.add.at(counts, (i, j), 1)
        expect = m[k] / m[k].sum() * n
        assert counts[expect == 0].sum() == 0
        o = expect > 0
        chi2 = (((counts - expect) ** 2)[o] / expect[o]).sum()
        dof = o.sum() - 1
        assert chi2 < dof + 5 * math.sqrt(2 * dof)
        # weight = open area / lens area (shutter interval = reference exposure)
        area = m[k].sum() * pitch**2
        assert np.allclose(w, area / (math.pi * 2.5**2), rtol=1e-5)


def test_bitmap_discs_match_disc_schedule():
    """Prototype display (1280x1024, 13.62 um): R = 145.5 px, R_max for F2.8 vs F9.85."""
    R = 145.5 * LCOS_PITCH_MM
    R_max = R * 9.85 / 2.8
    centres = np.array([[1.5, 1.0], [-2.0, 0.5], [0.0, -1.8], [2.5, -1.0]])
    masks = disc_masks(centres, R, supersample=4)
    common = dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=R_max,
        aperture_radius=R,
        shutter_open=0.0,
        shutter_close=4.0,
        film=film(W),
    )
    Z = 600.0  # defocus radius beta R = 1.2 px, centres shift the image by up to 1.9 px
    disc = psf_scene(ac.sensor_dict(schedule="centres", centres=centres, **common), Z)
    bmp = psf_scene(ac.sensor_dict(schedule="bitmap", masks=masks, **common), Z)
    beta = beta_px_per_mm(Z, ZF, FOV, W)
    sens_d, sens_b = disc.sensors()[0], bmp.sensors()[0]
    for k in range(4):  # each pattern's window: the same disc
        sens_d.configure(time_window=(k, k + 1))
        sens_b.configure(time_window=(k, k + 1))
        a, b = render(disc, 32, seed=1), render(bmp, 32, seed=2)
        ua, va = centroid(a)
        ub, vb = centroid(b)
        assert (ub, vb) == pytest.approx((ua, va), abs=0.03)
        assert ub == pytest.approx(W / 2 - beta * centres[k, 0], abs=0.05)
        assert vb == pytest.approx(W / 2 - beta * centres[k, 1], abs=0.05)
        assert b.sum() == pytest.approx(a.sum(), rel=0.005)  # rasterised area
    sens_d.configure(time_window=None)
    sens_b.configure(time_window=None)
    a1, a2, b = render(disc, 256, seed=1), render(disc, 256, seed=3), render(bmp, 256, seed=2)
    noise = rel_l1(a1, a2)  # ~0.002: the tolerance below is a few times the noise
    assert noise < 0.008
    assert rel_l1(a1, b) < 0.01  # a mirrored or mis-scaled mask gives > 0.3
    assert b.sum() == pytest.approx(a1.sum(), rel=0.005)


def test_bitmap_tables_kept_until_the_masks_change():
    """A capture's time steps re-configure the window only: the masks' tables are kept (each
    step re-read, checked and tabulated 64 full-display masks, 1.3 s a step); new masks, a new
    pitch or a new lens rebuild and re-check them."""
    R = 20 * LCOS_PITCH_MM
    masks = disc_masks([[0.0, 0.0], [0.2, 0.0]], R, shape=(64, 80))
    sensor = mi.load_dict(
        ac.sensor_dict(lens_radius=1.0, schedule="bitmap", masks=masks, fov=FOV,
                       focus_distance=ZF, shutter_open=0.0, shutter_close=2.0, film=film(8))
    )  # fmt: skip
    tables = sensor.plan.tables
    sensor.configure(time_window=(0.0, 1.0))
    sensor.configure(time_window=(0.5, 1.5, 1.0), focus_distance=ZF + 1)
    assert sensor.plan.tables is tables
    wider = disc_masks([[0.0, 0.0], [0.2, 0.0]], 1.5 * R, shape=(64, 80))
    sensor.configure(masks=mi.TensorXf(wider))
    assert sensor.plan.tables is not tables
    assert sensor.plan.tables.area_mm2 == pytest.approx(wider.sum(axis=(1, 2)) * LCOS_PITCH_MM**2)
    with pytest.raises(ParameterError, match="outside the lens"):
        sensor.configure(lens_radius=0.4)  # the kept masks are checked against the new lens
    assert sensor.plan.lens_radius_mm == 1.0  # refused: nothing changed


def test_the_plugin_takes_the_tables_sensor_dict_built_for_the_same_masks_and_lens():
    from pacam_render.render.plan import handed

    masks = disc_masks([[0.0, 0.0], [0.2, 0.0]], 20 * LCOS_PITCH_MM, shape=(64, 80))
    sd = ac.sensor_dict(lens_radius=1.0, schedule="bitmap", masks=masks, fov=FOV,
                        focus_distance=ZF, shutter_open=0.0, shutter_close=2.0,
                        film=film(8))  # fmt: skip
    built = handed(sd["mask_tables"], {"masks": masks, "lens_radius": 1.0})
    assert built is not None and mi.load_dict(sd).plan.tables is built
    other = mi.load_dict({**sd, "lens_radius": 0.9})  # edited after sensor_dict: rebuilt
    assert other.plan.tables is not built and other.plan.lens_radius_mm == 0.9
    assert np.array_equal(other.plan.tables.cdf, built.cdf)  # from the same masks


# ------------------------------------------------------------------------------------------
# 4. brightness follows open area and exposure
# ------------------------------------------------------------------------------------------


def _psf_sum(Z=1000.0, spp=16, **kw):
    params = dict(fov=FOV, focus_distance=ZF, lens_radius=8.0, film=film(32))
    params.update(kw)
    return render(psf_scene(ac.sensor_dict(**params), Z), spp, seed=7).sum()


def test_brightness_follows_open_area():
    full = _psf_sum()
    ref = dict(type="thinlens", fov=FOV, focus_distance=ZF, film=film(32))
    thin_full = render(psf_scene(dict(ref, aperture_radius=8.0), 1000.0), 16, seed=7).sum()
    thin_small = render(psf_scene(dict(ref, aperture_radius=3.0), 1000.0), 16, seed=7).sum()
    assert full == pytest.approx(thin_full, rel=1e-4)  # float atomics: order varies
    assert thin_small == pytest.approx(thin_full, rel=0.01)  # thinlens ignores the area
    for R in (4.0, 2.0):
        assert _psf_sum(aperture_radius=R) == pytest.approx(full * (R / 8.0) ** 2, rel=0.002)
    # a grey mask transmits in proportion to its grey level, a binary one to its area
    m = disc_masks([0.0], 3.0, shape=(600, 600))
    binary = _psf_sum(schedule="bitmap", masks=m)
    grey = _psf_sum(schedule="bitmap", masks=0.5 * m)
    assert binary == pytest.approx(full * m.sum() * LCOS_PITCH_MM**2 / (math.pi * 64), rel=2e-3)
    assert grey == pytest.approx(0.5 * binary, rel=2e-3)


def test_brightness_follows_exposure():
    base = dict(reference_exposure=10.0, shutter_open=0.0)
    e10 = _psf_sum(shutter_close=10.0, **base)
    e20 = _psf_sum(shutter_close=20.0, **base)
    e5 = _psf_sum(shutter_close=5.0, **base)
    assert e20 == pytest.approx(2.0 * e10, rel=2e-3)
    assert e5 == pytest.approx(0.5 * e10, rel=2e-3)
    # default reference = the shutter interval: equal to thinlens at any exposure
    assert _psf_sum(shutter_open=0.0, shutter_close=20.0) == pytest.approx(e10, rel=2e-3)
    # parabolic at R: open area (R/R_max)^2 for the whole exposure
    par = _psf_sum(schedule="parabolic", aperture_radius=3.0, shutter_close=20.0, **base)
    assert par == pytest.approx(2.0 * e10 * (3.0 / 8.0) ** 2, rel=2e-3)
    # fluttered shutter: open 26 of 52 chops
    code = sch.flutter_code()
    flut = _psf_sum(schedule="flutter", shutter_close=10.0, **base)
    assert flut == pytest.approx(e10 * code.sum() / len(code), rel=2e-3)
    assert code.sum() / len(code) == 0.5
    other = "1100000000000000000000000000000000000000000000000000"  # 2 of 52 open
    flut2 = _psf_sum(schedule="flutter", flutter_code=other, shutter_close=10.0, **base)
    assert flut2 == pytest.approx(e10 * 2 / 52, rel=2e-3)


def test_plan_mean_weight_predicts_brightness():
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=8.0,
        aperture_radius=3.0,
        schedule="flutter",
        shutter_open=0.0,
        shutter_close=10.0,
        reference_exposure=4.0,
        film=film(32),
    )
    scene = psf_scene(sd, 1000.0)
    s = render(scene, 16, seed=7).sum()
    full = _psf_sum()
    plan = scene.sensors()[0].plan
    assert plan.mean_weight() == pytest.approx((3 / 8) ** 2 * 0.5 * 10 / 4)
    assert s == pytest.approx(full * plan.mean_weight(), rel=2e-3)


# ------------------------------------------------------------------------------------------
# 5. pattern boundaries
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "n, t0, t1", [(16, 0.0, 45.0), (7, 3.1, 48.1), (5, -10.0, 1.7), (11, 1000.3, 1045.3)]
)
def test_pattern_boundaries(n, t0, t1):
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=8.0,
        aperture_radius=2.0,
        schedule="parabolic",
        n_patterns=n,
        shutter_open=t0,
        shutter_close=t1,
        film=film(8),
    )
    sensor = mi.load_dict(sd)
    edges = np.linspace(t0, t1, n + 1)
    e32 = edges.astype(np.float32)
    times = np.concatenate(
        [
            e32,
            np.nextafter(e32, np.float32(np.inf)),
            np.nextafter(e32, np.float32(-np.inf)),
            (0.5 * (edges[:-1] + edges[1:])).astype(np.float32),
        ]
    )
    times = times[(times >= np.float32(t0)) & (times <= np.float32(t1))]
    T = 0.5 * (t1 - t0)
    expect = sch.pattern_index(times.astype(np.float64) - 0.5 * (t0 + t1), T, n)
    assert np.array_equal(sensor.pattern_index(times), expect)
    assert np.array_equal(sensor.plan.pattern_at(times.astype(np.float64)), expect)
    # exactly at a boundary: the later pattern; t = close: the last one
    exact = np.flatnonzero(e32.astype(np.float64) == edges)
    for i in exact:
        assert sensor.pattern_index(e32[i : i + 1])[0] == min(i, n - 1)


def test_ray_time_selects_its_pattern():
    """End to end: the ray leaves from the centre of the pattern its time selects."""
    centres = np.array([-0.6, -0.4, -0.2, 0.0, 0.2, 0.4, 0.6])
    sensor = mi.load_dict(
        ac.sensor_dict(
            fov=FOV,
            focus_distance=ZF,
            lens_radius=2.0,
            aperture_radius=0.1,
            schedule="centres",
            centres=centres,
            shutter_open=3.1,
            shutter_close=48.1,
            near_clip=1e-4,
            film=film(8),
        )
    )
    edges = np.linspace(3.1, 48.1, 8).astype(np.float32)
    times = np.concatenate([edges, np.nextafter(edges, np.float32(-np.inf))])
    times = times[(times >= np.float32(3.1)) & (times <= np.float32(48.1))]
    n = len(times)
    ray, _ = sensor.sample_ray(
        mi.Float(times), mi.Float(np.full(n, 0.5)), mi.Point2f(0.5, 0.5), mi.Point2f(0.5, 0.5)
    )
    k = np.argmin(np.abs(np.array(ray.o.x)[:, None] - centres[None, :]), axis=1)
    assert np.array_equal(k, sch.pattern_index(times.astype(np.float64) - 25.6, 22.5, 7))
    assert np.allclose(np.array(ray.time), times)


def test_flutter_chops_open_and_close_at_boundaries():
    code = sch.flutter_code()
    sensor = mi.load_dict(
        ac.sensor_dict(
            fov=FOV,
            focus_distance=ZF,
            lens_radius=2.0,
            schedule="flutter",
            shutter_open=0.0,
            shutter_close=52.0,  # 1 ms chops
            film=film(8),
        )
    )
    t = np.concatenate([np.arange(52) + 0.0, np.arange(52) + 0.999])
    _, _, w = sensor.sample_aperture(t, np.full(t.size, 0.3), np.full(t.size, 0.6))
    assert np.array_equal(w > 0, np.concatenate([code, code]) > 0)
    assert np.allclose(w[w > 0], 0.5)  # full lens, open half the time: ray weight E/E_ref
    # camera rays never sample a closed chop
    rng = np.random.default_rng(0)
    u = rng.random(20000)
    ray, wr = sensor.sample_ray(
        mi.Float(52.0 * u), mi.Float(u), mi.Point2f(u, u), mi.Point2f(u[::-1], u)
    )
    chop = np.floor(np.array(ray.time)).astype(int)
    assert np.all(code[np.minimum(chop, 51)] == 1)
    assert np.allclose(np.array(wr)[0], 0.5)
    hist = np.bincount(chop, minlength=52)[code > 0]
    assert hist.min() > 0.8 * u.size / 26  # uniform over the open chops


# ------------------------------------------------------------------------------------------
# 6. the parabola of Eq. 2 with the a_i of Eq. 18
# ------------------------------------------------------------------------------------------

R_MAX, R_OPEN, T_HALF, NPAT = 16.0, 6.0, 22.5, 16


def _window_centroids(scene, n, t0, t1, spp=16):
    sensor = scene.sensors()[0]
    edges = np.linspace(t0, t1, n + 1)
    out = []
    for k in range(n):
        sensor.configure(time_window=(edges[k], edges[k + 1]))
        out.append(centroid(render(scene, spp, seed=k)))
    sensor.configure(time_window=None)
    return np.array(out), edges


@pytest.mark.parametrize("continuous", [False, True])
def test_parabolic_trajectory(continuous):
    Z = 1000.0
    beta = beta_px_per_mm(Z, ZF, FOV, W)
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=R_MAX,
        aperture_radius=R_OPEN,
        schedule="parabolic",
        continuous=continuous,
        shutter_open=0.0,
        shutter_close=2 * T_HALF,
        film=film(W),
    )
    c, edges = _window_centroids(psf_scene(sd, Z), NPAT, 0.0, 2 * T_HALF)
    t_mid = 0.5 * (edges[:-1] + edges[1:]) - T_HALF  # paper time
    a_a = sch.aperture_acceleration(R_MAX, R_OPEN, T_HALF)
    if continuous:  # mean of X_a over each window: t^2 averages to t_mid^2 + dt^2/12
        dt = edges[1] - edges[0]
        x_a = -(0.5 * a_a * (t_mid**2 + dt**2 / 12) - (R_MAX - R_OPEN))
    else:  # the schedule runs along local -x (the image's +u axis)
        x_a = -sch.pattern_centres_mm(R_MAX, R_OPEN, T_HALF, NPAT)
    assert np.abs(c[:, 0] - (W / 2 - beta * x_a)).max() < 0.05  # Eq. 8, pattern by pattern
    assert np.abs(c[:, 1] - W / 2).max() < 0.05
    # Eq. 2: x(t) = x0 + a_i t^2 / 2 with a_i from Eq. 18, sign included (+beta a_a)
    a_i = 2 * np.polyfit(t_mid, c[:, 0], 2)[0]
    eq18 = sch.image_acceleration(beta, R_MAX, R_OPEN, T_HALF)
    assert a_i == pytest.approx(eq18, rel=0.01)
    assert eq18 == pytest.approx(4 * beta * (R_MAX - R_OPEN) / T_HALF**2)


@pytest.mark.parametrize("continuous", [True, False])
def test_camera_parabolic_trajectory(continuous):
    """Levin's camera, focused: the image moves by +f_px X_c(t) / Z; a_i given per Eq. 18."""
    beta = beta_px_per_mm(1000.0, ZF, FOV, W)
    a_i = sch.image_acceleration(beta, R_MAX, R_OPEN, T_HALF)  # the coded camera's a_i
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=R_MAX,
        aperture_radius=R_OPEN,
        schedule="camera_parabolic",
        image_acceleration=a_i,
        continuous=continuous,
        shutter_open=0.0,
        shutter_close=2 * T_HALF,
        film=film(W),
    )
    f_px = focal_length_px(FOV, W)
    # in focus: the image is the emitter itself, a disc of radius f_px r / Z = 1.5 px
    scene = psf_scene(sd, ZF, r=1.5 * ZF / f_px)
    c, edges = _window_centroids(scene, NPAT, 0.0, 2 * T_HALF)
    t_mid = 0.5 * (edges[:-1] + edges[1:]) - T_HALF
    a_c = a_i * ZF / f_px  # mm/ms^2
    dt = edges[1] - edges[0]
    t2 = t_mid**2 + (dt**2 / 12 if continuous else 0.0)
    x_c = a_c * (0.5 * t2 - 0.25 * T_HALF**2)
    assert np.abs(c[:, 0] - (W / 2 + f_px * x_c / ZF)).max() < 0.05  # Eq. 4
    assert np.abs(c[:, 1] - W / 2).max() < 0.05
    assert 2 * np.polyfit(t_mid, c[:, 0], 2)[0] == pytest.approx(a_i, rel=0.01)
    plan = scene.sensors()[0].plan
    t_end = T_HALF if continuous else t_mid[-1]  # discrete: constant over the last pattern
    assert plan.camera_offset_at(np.array([2 * T_HALF]))[0] == pytest.approx(
        a_c * (0.5 * t_end**2 - 0.25 * T_HALF**2)
    )
    # the camera body's travel is in the bounding box
    box = scene.sensors()[0].bbox()
    x_steps = a_c * (0.5 * t_mid**2 - 0.25 * T_HALF**2)  # the discrete camera's positions
    travel = 0.5 * a_c * T_HALF**2 if continuous else np.ptp(x_steps)
    assert box.max.x - box.min.x == pytest.approx(travel, rel=1e-4)


# ------------------------------------------------------------------------------------------
# path tracing (sample_ray) and particle tracing (sample_direction) agree for all schedules
# ------------------------------------------------------------------------------------------

SCHEDULES = {
    "parabolic": dict(schedule="parabolic"),
    "flutter": dict(schedule="flutter"),
    "camera_parabolic": dict(schedule="camera_parabolic", image_acceleration=0.05),
    "bitmap": dict(
        schedule="bitmap",
        masks=disc_masks(sch.pattern_centres_mm(8.0, 3.0, 22.5, 16), 3.0, supersample=2),
    ),
    "time_window": dict(schedule="parabolic", time_window="5, 12"),
}


@pytest.mark.parametrize("name", list(SCHEDULES))
def test_path_and_particle_tracer_agree(name):
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=500.0,
        lens_radius=8.0,
        aperture_radius=3.0,
        shutter_open=0.0,
        shutter_close=45.0,
        film=film(48),
        **SCHEDULES[name],
    )
    path = render(wall_scene(sd, "path"), 64, seed=1)
    path2 = render(wall_scene(sd, "path"), 64, seed=2)
    pt = render(wall_scene(sd, "ptracer"), 64, seed=1)
    pt2 = render(wall_scene(sd, "ptracer"), 64, seed=2)
    # L1 of two independent renders is ~ sqrt(2) sigma: combine the two noise levels
    n_path = rel_l1(blocks(path), blocks(path2))
    n_pt = rel_l1(blocks(pt), blocks(pt2))
    expected = math.sqrt(0.5 * (n_path**2 + n_pt**2))
    assert rel_l1(blocks(path), blocks(pt)) < 1.4 * expected
    assert expected < 0.05  # a meaningful comparison (a wrong sign gave 0.8)
    assert pt.mean() == pytest.approx(path.mean(), rel=0.01)
    # and the level is the open area x open time of the plan (thinlens = 1)
    plan = wall_scene(sd, "path").sensors()[0].plan
    full = ac.sensor_dict(
        fov=FOV,
        focus_distance=500.0,
        lens_radius=8.0,
        shutter_open=0.0,
        shutter_close=45.0,
        film=film(48),
    )
    ref = render(wall_scene(full, "path"), 64, seed=1)
    assert path.mean() == pytest.approx(ref.mean() * plan.mean_weight(), rel=0.01)


def test_time_windows_sum_to_the_exposure():
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=500.0,
        lens_radius=8.0,
        aperture_radius=3.0,
        schedule="flutter",
        shutter_open=0.0,
        shutter_close=45.0,
        film=film(48),
    )
    scene = wall_scene(sd, "path")
    sensor = scene.sensors()[0]
    full = render(scene, 64, seed=1)
    parts = 0.0
    for a, b in ((0, 10), (10, 11), (11, 30), (30, 45)):
        sensor.configure(time_window=(a, b))
        parts = parts + render(scene, 64, seed=a + 2)
    sensor.configure(time_window=None)
    assert parts.mean() == pytest.approx(full.mean(), rel=0.01)
    assert rel_l1(blocks(full), blocks(parts)) < 0.05


# ------------------------------------------------------------------------------------------
# opaque parameters: no recompilation
# ------------------------------------------------------------------------------------------


def _all_cached(scene) -> bool:
    with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
        mi.render(scene, spp=2)
        hist = dr.kernel_history([dr.KernelType.JIT])
    assert hist
    return all(h["cache_hit"] for h in hist)


@pytest.mark.parametrize("integrator", ["path", "ptracer"])
def test_new_radius_or_schedule_does_not_recompile(integrator):
    """Sweeping values never recompiles; each schedule type compiles its kernel once."""
    sd = ac.sensor_dict(
        fov=FOV,
        focus_distance=ZF,
        lens_radius=8.0,
        aperture_radius=3.0,
        schedule="parabolic",
        shutter_open=0.0,
        shutter_close=45.0,
        film=film(16),
    )
    scene = wall_scene(sd, integrator)
    sensor = scene.sensors()[0]
    mi.render(scene, spp=2)
    params = mi.traverse(scene)
    params["sensor.aperture_radius"] = 2.5  # the scene's first update may recompile once
    params.update()
    mi.render(scene, spp=2)
    for R in (1.0, 2.0):  # through mi.traverse
        params["sensor.aperture_radius"] = R
        params.update()
        assert sensor.plan.radius_mm == pytest.approx(R)
        assert _all_cached(scene), f"aperture_radius={R}"
    for change in (  # through configure: new values of the same schedule
        dict(aperture_radius=0.5),
        dict(n_patterns=9),
        dict(lens_radius=6.0),
        dict(focus_distance=300.0),
    ):
        sensor.configure(**change)
        assert _all_cached(scene), change
    sweeps = [  # (first value, later values) per schedule type
        (dict(schedule="static"), [dict(aperture_radius=2.0)]),
        (
            dict(schedule="centres", centres=np.array([[0.5, 0.2], [-0.5, 0.1], [0.0, 0.0]])),
            [dict(centres=np.array([[1.0, -0.2], [0.0, 0.0]]))],
        ),
        (dict(schedule="flutter"), [dict(flutter_code="1011"), dict(aperture_radius=1.0)]),
        (
            dict(schedule="camera_parabolic", camera_acceleration=0.01),
            [dict(camera_acceleration=-0.02), dict(image_acceleration=0.1)],
        ),
        (dict(schedule="parabolic", continuous=True), [dict(aperture_radius=1.5)]),
        (dict(schedule="parabolic", time_window=(3.0, 9.0)), [dict(time_window=(1.0, 2.0))]),
        (
            dict(schedule="bitmap", masks=disc_masks([[0.5, 0.0], [-0.5, 0.0]], 1.0, (400, 400))),
            [dict(masks=disc_masks([[0.4, 0.1], [-0.5, 0.0], [0, 0]], 1.2, (300, 400)))],
        ),
    ]
    for first, later in sweeps:
        sensor.configure(**{"time_window": None, **first})
        mi.render(scene, spp=2)  # this schedule type's kernel, compiled once
        for change in later:
            sensor.configure(**change)
            assert _all_cached(scene), change
    for first, _ in sweeps:  # every type's kernel stays cached
        sensor.configure(**{"time_window": None, **first})
        assert _all_cached(scene), first


# ------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------

GOOD = dict(fov=FOV, focus_distance=ZF, lens_radius=4.0, shutter_open=0.0, shutter_close=10.0)


@pytest.mark.parametrize(
    "change, match",
    [
        (dict(aperture_radius=-1.0), "aperture_radius"),
        (dict(aperture_radius=0.0), "aperture_radius"),
        (dict(aperture_radius=5.0), "aperture_radius"),
        (dict(lens_radius=-2.0), "lens_radius"),
        (dict(schedule="centres", aperture_radius=1.0, centres="3.5 0; 0 0"), "outside the lens"),
        (dict(schedule="centres", aperture_radius=1.0, centres="2 2.5"), "outside the lens"),
        (dict(schedule="centres"), "centres"),
        (dict(schedule="bitmap", masks=np.zeros((2, 50, 50))), "black"),
        (dict(schedule="bitmap", masks=np.ones((50, 50)), mask_pitch=0.2), "outside the lens"),
        (dict(schedule="bitmap", masks=np.zeros((0, 5, 5))), "empty"),
        (dict(schedule="bitmap"), "masks"),
        (dict(schedule="parabolic", shutter_close=0.0), "shutter_close > shutter_open"),
        (dict(schedule="flutter", shutter_close=0.0), "shutter_close > shutter_open"),
        (dict(schedule="camera_parabolic", shutter_close=0.0), "shutter_close"),
        (dict(schedule="centres", centres="0 0; 1 0", shutter_close=0.0), "shutter_close"),
        (dict(schedule="camera_parabolic"), "camera_acceleration"),
        (
            dict(schedule="camera_parabolic", camera_acceleration=1, image_acceleration=1),
            "exactly one",
        ),
        (dict(schedule="sinusoidal"), "schedule must be one of"),
        (dict(n_patterns=0, schedule="parabolic"), "n_patterns"),
        (dict(schedule="flutter", n_patterns=16), "n_patterns"),
        (dict(schedule="flutter", flutter_code="0000"), "flutter code"),
        (dict(schedule="static", continuous=True), "continuous"),
        (dict(reference_exposure=-1.0), "reference_exposure"),
        (dict(time_window="5, 20"), "time_window"),
        (dict(focus_distance=-1.0), "focus_distance"),
        (dict(schedule="parabolic", shutter_open=1e7, shutter_close=1e7 + 1), "float32"),
    ],
)
def test_bad_input_raises_clear_errors(change, match):
    params = dict(GOOD, film=film(8))
    params.update(change)
    with pytest.raises(ParameterError, match=match):
        ac.sensor_dict(**params)
    params["type"] = ac.PLUGIN_NAME
    for k in ("masks", "centres"):
        if isinstance(params.get(k), np.ndarray):
            params[k] = mi.TensorXf(params[k].astype(np.float32))
    with pytest.raises(RuntimeError, match=match):
        mi.load_dict(params)


def test_errors_leave_the_sensor_unchanged():
    sensor = mi.load_dict(ac.sensor_dict(schedule="parabolic", aperture_radius=1.0, **GOOD))
    before = sensor.plan
    with pytest.raises(ParameterError, match="aperture_radius"):
        sensor.configure(aperture_radius=4.5)
    with pytest.raises(ParameterError, match="unknown"):
        sensor.configure(radius=1.0)
    assert sensor.plan is before
    params = mi.traverse(sensor)
    params["aperture_radius"] = 9.0
    with pytest.raises(ParameterError, match="aperture_radius"):
        params.update()
    assert sensor.plan is before
    with pytest.raises(RuntimeError, match="scale factors"):
        mi.load_dict(dict(ac.sensor_dict(**GOOD), to_world=T_().scale(2.0)))


# ------------------------------------------------------------------------------------------
# plumbing: registration, XML, traversal, bbox, to_string, scalar variant
# ------------------------------------------------------------------------------------------


def test_register_is_idempotent_and_follows_variant_switches():
    ac.install()
    ac.install()
    assert ac.register() == mi.variant()
    assert ac.register() == mi.variant()
    current = mi.variant()
    try:
        mi.set_variant("scalar_rgb")  # the variant callback registers again
        s = mi.load_dict(ac.sensor_dict(**GOOD))
        assert "ProgrammableApertureCamera" in str(s)
    finally:
        mi.set_variant(current)
    s = mi.load_dict(ac.sensor_dict(**GOOD))
    assert s.plan.schedule == "static"


def test_scalar_variant_matches_thinlens():
    current = mi.variant()
    try:
        mi.set_variant("scalar_rgb")
        ac.register()
        f = film(12, 10, "rgb")
        ours = ac.sensor_dict(lens_radius=25.0, film=f, to_world=tilt(), **THIN)
        ref = dict(type="thinlens", aperture_radius=25.0, film=f, to_world=tilt(), **THIN)
        a = render(wall_scene(ref, "path"), 2, seed=3)
        b = render(wall_scene(ours, "path"), 2, seed=3)
        assert rel_l1(a, b) < 1e-4
        par = ac.sensor_dict(
            lens_radius=25.0, aperture_radius=5.0, schedule="parabolic", film=f, **THIN
        )
        img = render(wall_scene(par, "ptracer"), 2, seed=3)
        assert np.isfinite(img).all() and img.sum() > 0
        m = disc_masks([[-2.0, 1.0], [3.0, 0.0]], 5.0, shape=(80, 80), pitch_mm=0.2)
        m[1] *= 0.5
        bmp = ac.sensor_dict(
            lens_radius=25.0, schedule="bitmap", masks=m, mask_pitch=0.2, film=f, **THIN
        )
        for integrator in ("path", "ptracer"):
            img = render(wall_scene(bmp, integrator), 2, seed=3)
            assert np.isfinite(img).all() and img.sum() > 0
    finally:
        mi.set_variant(current)


def test_xml_scene(tmp_path):
    m = disc_masks([0.0, 0.5], 1.0, shape=(300, 300))
    np.save(tmp_path / "masks.npy", m)
    xml = f"""<scene version="3.0.0">
  <sensor type="programmable_aperture">
    <float name="fov" value="30"/>
    <float name="focus_distance" value="250"/>
    <float name="lens_radius" value="2.5"/>
    <float name="aperture_radius" value="1"/>
    <float name="shutter_open" value="0"/>
    <float name="shutter_close" value="45"/>
    <integer name="n_patterns" value="8"/>
    <string name="schedule" value="parabolic"/>
    <boolean name="continuous" value="true"/>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/>
    </film>
  </sensor>
  <sensor type="programmable_aperture">
    <float name="lens_radius" value="2.5"/>
    <float name="shutter_close" value="2"/>
    <string name="schedule" value="bitmap"/>
    <string name="mask_file" value="{tmp_path / "masks.npy"}"/>
  </sensor>
  <sensor type="programmable_aperture">
    <float name="lens_radius" value="2.5"/>
    <float name="aperture_radius" value="0.5"/>
    <float name="shutter_close" value="3"/>
    <string name="schedule" value="centres"/>
    <string name="centres" value="1 0; -1 0.5; 0 -1.2"/>
    <string name="time_window" value="1, 2"/>
  </sensor>
</scene>"""
    scene = mi.load_string(xml)
    a, b, c = scene.sensors()
    assert a.plan.schedule == "parabolic" and a.plan.continuous and a.plan.n_patterns == 1
    assert b.plan.n_patterns == 2 and b.plan.area_mm2[0] == pytest.approx(
        m[0].sum() * LCOS_PITCH_MM**2
    )
    assert np.allclose(c.plan.centres_mm, [[1, 0], [-1, 0.5], [0, -1.2]])
    assert c.plan.window == (1.0, 2.0)


def test_traverse_bbox_and_to_string():
    sd = ac.sensor_dict(schedule="parabolic", aperture_radius=1.0, to_world=tilt(), **GOOD)
    sensor = mi.load_dict(sd)
    params = mi.traverse(sensor)
    for key in ("to_world", "aperture_radius", "lens_radius", "focus_distance"):
        assert key in params
    text = str(sensor)
    for word in ("parabolic", "n_patterns = 16", "aperture_radius = 1 mm", "lens_radius = 4 mm"):
        assert word in text
    box = sensor.bbox()
    assert np.allclose([box.min.x, box.min.y, box.min.z], [30, -20, 0], atol=1e-4)
    # moving the camera through traverse moves its rays
    params["to_world"] = T_().translate([5.0, 0.0, 0.0])
    params.update()
    ray, _ = sensor.sample_ray(mi.Float(5.0), mi.Float(0.5), mi.Point2f(0.5), mi.Point2f(0.5))
    assert float(ray.o.x[0]) == pytest.approx(
        5.0 + sensor.plan.aperture_centre_at(5.0)[0], abs=1e-3
    )
    assert sensor.bbox().min.x == pytest.approx(5.0)
    # focus through traverse
    params["focus_distance"] = 321.0
    params.update()
    assert sensor.focus_distance() == pytest.approx(321.0)
