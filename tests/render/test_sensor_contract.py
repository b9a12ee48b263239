"""``programmable_aperture`` keeps Mitsuba's sensor contract, as ``thinlens`` does.

Mitsuba's own sensor and particle-tracer tests hold a sensor to a contract around its rays
(issue 37, items 1-4). These are the project's own tests of that contract, each run on our
sensor (fully open, so that it must trace thinlens' rays) and on ``thinlens`` as the control,
in ``llvm_ad_rgb`` and ``scalar_rgb``:

1. a film crop or size changed at run time through ``mi.traverse`` and ``params.update()``
   rebuilds the projection: the render equals one with that film given at load time, exactly,
   in ``path`` and ``ptracer``;
2. ``bbox()`` works in every variant (a point at the lens centre for a still camera);
3. the methods take Python lists, tuples and numbers as Mitsuba's tests pass them, and convert
   them as thinlens' bindings do;
4. ``near_clip()``, ``far_clip()`` and ``focus_distance()`` are methods, and ``near_clip``,
   ``far_clip`` and ``x_fov`` are exposed to ``mi.traverse``: changing them moves the rays as
   it does for thinlens, and a bad value is refused with the sensor left unchanged.

The one expected difference: a thin lens needs an aperture sample (``needs_aperture_sample``).
"""

from __future__ import annotations

import os
import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from pacam_render import render as ac
from pacam_render.errors import ParameterError
from pacam_render.render.variant import llvm_status

VARIANTS = ["llvm_ad_rgb", "scalar_rgb"]
R = 2.0  # lens radius = aperture radius (mm): fully open, so it must trace thinlens' rays
ORIGIN = [1.0, 4.0, 1.5]
DIRECTION = [1.0, 0.0, 0.0]


@pytest.fixture(params=VARIANTS)
def variant(request):
    """Activate the variant (our sensors follow it) and restore the previous one after."""
    before = mi.variant()
    if request.param.startswith("llvm"):
        ok, why = llvm_status()
        if not ok:
            pytest.skip(f"LLVM backend unavailable: {why}")
    mi.set_variant(request.param)
    ac.register()
    yield request.param
    if before is not None:
        mi.set_variant(before)


def T_():
    return mi.ScalarTransform4f()


def look(origin=ORIGIN, direction=DIRECTION):
    target = [o + d for o, d in zip(origin, direction)]
    return T_().look_at(origin=origin, target=target, up=[0, 1, 0])


def film(width=16, height=12, crop=None):
    """A box-filtered float32 RGB film; ``crop`` = ((offset x, y), (width, height))."""
    f = {
        "type": "hdrfilm",
        "width": width,
        "height": height,
        "rfilter": {"type": "box"},
        "pixel_format": "rgb",
        "component_format": "float32",
    }
    if crop is not None:
        (ox, oy), (cw, ch) = crop
        f.update(crop_offset_x=ox, crop_offset_y=oy, crop_width=cw, crop_height=ch)
    return f


def camera(kind: str, **kw) -> dict:
    """The sensor entry of ``kind`` ("ours" or "thinlens") with the same optics."""
    d = dict(
        fov=34.0,
        fov_axis="x",
        near_clip=1.0,
        far_clip=35.0,
        focus_distance=15.0,
        shutter_open=1.5,
        shutter_close=5.0,
        to_world=look(),
        film=film(512, 256),
    )
    d.update(kw)
    if kind == "ours":
        return ac.sensor_dict(lens_radius=R, **d)
    return dict(type="thinlens", aperture_radius=R, **d)


def both(**kw):
    """(ours, thinlens), loaded with the same parameters."""
    return mi.load_dict(camera("ours", **kw)), mi.load_dict(camera("thinlens", **kw))


def arr(v) -> np.ndarray:
    """``v`` as float64 numpy, one-lane JIT values shaped as in scalar variants."""
    return np.squeeze(np.array(v, dtype=np.float64))


def close(a, b, atol=1e-5):
    return np.allclose(arr(a), arr(b), atol=atol, rtol=1e-5)


# ------------------------------------------------------------------------------------------
# 1. A film crop or size changed at run time rebuilds the projection
# ------------------------------------------------------------------------------------------

CROP = ((3, 2), (9, 7))  # offset, size: off-centre, so the centre ray must tilt


def wall_scene(kind: str, integrator: str, f: dict):
    """A lit checkerboard wall in front of the camera (texture, so a wrong projection shows),
    rendered by ``integrator`` through sensor ``kind`` with film ``f``."""
    sensor = camera(
        kind,
        fov=40.0,
        near_clip=0.01,
        far_clip=1e4,
        focus_distance=600.0,
        shutter_open=0.0,
        shutter_close=10.0,
        to_world=T_().look_at(origin=[20, -10, 0], target=[0, 0, 1000], up=[0, 1, 0]),
        film=f,
        sampler={"type": "independent"},
    )
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator, "max_depth": 3},
            "sensor": sensor,
            "wall": {
                "type": "rectangle",
                "to_world": T_().translate([0, 0, 1000])
                @ T_().rotate([1, 0, 0], 180)
                @ T_().scale(500),
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": {
                        "type": "checkerboard",
                        "to_uv": mi.ScalarTransform3f().scale(7),
                    },
                },
            },
            "light": {
                "type": "spot",
                "cutoff_angle": 40.0,
                "beam_width": 35.0,
                "to_world": T_().look_at(origin=[0, 0, 400], target=[0, 0, 1000], up=[0, 1, 0]),
                "intensity": {"type": "rgb", "value": 1e5},
            },
        }
    )


def render(scene) -> np.ndarray:
    return np.array(mi.render(scene, spp=4, seed=7), dtype=np.float64)


@pytest.fixture
def one_thread():
    """One Dr.Jit worker thread: the particle tracer's splats then add up in one order.

    With several, two renders of the same scene can differ by float32 rounding (seen: 1e-7
    relative, in about 1 of 30 ptracer renders, thinlens included); that is not the
    projection, which this module tests for exact equality.
    """
    before = dr.thread_count()
    dr.set_thread_count(1)
    yield
    dr.set_thread_count(before)


@pytest.mark.render
@pytest.mark.parametrize("kind", ["thinlens", "ours"])  # thinlens: the control
@pytest.mark.parametrize("integrator", ["path", "ptracer"])
@pytest.mark.parametrize("change", ["crop", "size"])
def test_film_changed_at_run_time_equals_film_given_at_load_time(
    variant, one_thread, integrator, kind, change
):
    """A crop (size and offset) or a film size set through mi.traverse, then
    params.update(), renders exactly what the same film given at load time renders."""
    scene = wall_scene(kind, integrator, film())
    render(scene)  # the first film's projection is in use before the change
    params = mi.traverse(scene)
    if change == "crop":
        (ox, oy), (cw, ch) = CROP
        params["sensor.film.crop_size"] = [cw, ch]
        params["sensor.film.crop_offset"] = [ox, oy]
        loaded = film(crop=CROP)
    else:
        params["sensor.film.size"] = [10, 14]  # the crop follows (the whole new film)
        loaded = film(10, 14)
    params.update()
    at_run_time = render(scene)
    at_load_time = render(wall_scene(kind, integrator, loaded))
    assert at_run_time.shape == at_load_time.shape
    assert at_load_time.sum() > 0 and np.isfinite(at_load_time).all()
    assert np.array_equal(at_run_time, at_load_time)


def test_crop_tilts_the_centre_ray_as_thinlens_does(variant):
    """After a run-time crop, the ray through the crop's centre is thinlens' ray."""
    rays = []
    for cam in both():
        params = mi.traverse(cam)
        params["film.crop_size"] = [100, 60]
        params["film.crop_offset"] = [20, 30]
        params.update()
        rays.append(cam.sample_ray(0.0, 0.5, [0.5, 0.5], [0.5, 0.5])[0])
    ours, ref = rays
    assert not close(ref.d, DIRECTION, atol=1e-3)  # the crop is off-centre: tilted
    assert close(ours.d, ref.d) and close(ours.o, ref.o, atol=1e-4)


# ------------------------------------------------------------------------------------------
# 2. bbox() in every variant
# ------------------------------------------------------------------------------------------


BBOX_SCALAR_ONLY = """
import mitsuba as mi
mi.set_variant("scalar_rgb")
from pacam_render import render as ac
ac.register()
cam = mi.load_dict(ac.sensor_dict(lens_radius=1.0, fov=30.0,
    to_world=mi.ScalarTransform4f().translate([1.0, 2.0, 3.0])))
box = cam.bbox()
assert box == mi.BoundingBox3f([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]), box
print("ok")
"""


def test_bbox_in_a_scalar_only_process():
    """In a process that never loaded a JIT variant, scalar variants have no
    ``ScalarBoundingBox3f``: bbox() must not need it."""
    env = {**os.environ, "PACAM_VARIANT": "scalar_rgb"}
    out = subprocess.run(
        [sys.executable, "-c", BBOX_SCALAR_ONLY], capture_output=True, text=True, env=env
    )
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_bbox_is_the_lens_centre_in_every_variant(variant):
    ours, ref = both()
    box = ours.bbox()
    assert box == ref.bbox()
    assert close(box.min, ORIGIN) and close(box.max, ORIGIN)
    if variant.startswith("scalar"):
        assert box == mi.BoundingBox3f(ORIGIN, ORIGIN)
    # a moving camera's box spans its travel (camera_parabolic moves along local +x)
    moving = mi.load_dict(
        camera("ours", schedule="camera_parabolic", camera_acceleration=0.5, aperture_radius=1.0)
    )
    xs = moving.plan.camera_offset_at(np.linspace(1.5, 5.0, 401))
    travel = xs.max() - xs.min()
    assert travel > 0.1
    box = moving.bbox()
    assert arr(box.max)[2] - arr(box.min)[2] == pytest.approx(travel, rel=1e-3)  # local x = -z


# ------------------------------------------------------------------------------------------
# 3. Arguments as Mitsuba's tests pass them
# ------------------------------------------------------------------------------------------


def _samples(variant):
    """(time, wavelength, position, aperture) as plain Python, as Mitsuba's tests write them:
    vectorised lists in the JIT variant, single values in scalar."""
    if variant.startswith("scalar"):
        return [(0.5, 0.33, [0.2, 0.6], [0.9, 0.6]), (0, 0, (0.5, 0.5), (0.5, 0.5))]
    return [
        (0.5, [0.5, 0.33, 0.1], [[0.2, 0.1, 0.2], [0.6, 0.9, 0.2]], [0.5, 0.5]),
        (0.0, [0.5, 0.33, 0.1], [0.5, 0.5], [[0.9, 0.4, 0.2], [0.6, 0.9, 0.7]]),
        (0, 0, [0.5, 0.5], [0.5, 0.5]),
    ]


def test_sample_ray_takes_python_arguments(variant):
    ours, ref = both()
    for args in _samples(variant):
        (r1, w1), (r2, w2) = ours.sample_ray(*args), ref.sample_ray(*args)
        for name in ("o", "d", "maxt", "time", "wavelengths"):
            assert close(getattr(r1, name), getattr(r2, name), atol=1e-4), (args, name)
        assert close(w1, w2), args
    ray, _ = ours.sample_ray(0, 0, [0.5, 0.5], [0.5, 0.5])  # upstream's centre-ray check
    assert close(ray.d, DIRECTION, atol=1e-6)
    ray, _ = ours.sample_ray(0.5, 0.5, [0.5, 0.5], [0.5, 0.5], True)  # active as a bool
    assert close(ray.d, DIRECTION, atol=1e-6)


def test_sample_ray_differential_takes_python_arguments(variant):
    ours, ref = both()
    for args in _samples(variant):
        (r1, w1), (r2, _) = ours.sample_ray_differential(*args), ref.sample_ray_differential(*args)
        for name in ("o", "d", "d_x", "d_y", "maxt", "time"):
            assert close(getattr(r1, name), getattr(r2, name), atol=1e-4), (args, name)
        assert close(w1, 1.0)
    # differentials: the rays one pixel over, through the same lens point
    ap = _samples(variant)[-1][3]
    centre, _ = ours.sample_ray_differential(0, 0, [0.5, 0.5], ap)
    size = ours.film().crop_size()
    rx, _ = ours.sample_ray_differential(0, 0, [0.5 + 1.0 / size.x, 0.5], ap)
    ry, _ = ours.sample_ray_differential(0, 0, [0.5, 0.5 + 1.0 / size.y], ap)
    assert close(rx.d, centre.d_x) and close(ry.d, centre.d_y)


def test_sample_direction_takes_python_arguments(variant):
    ours, ref = both()
    it = dr.zeros(mi.Interaction3f)
    it.p = mi.Point3f(11.0, 4.3, 1.2)  # in front of the camera (which looks along +x)
    it.time = 2.0
    samples = [[0.5, 0.5], (0.3, 0.8)]
    if not variant.startswith("scalar"):
        samples.append([[0.1, 0.5, 0.9], [0.7, 0.5, 0.2]])
    for sample in samples:
        (d1, w1), (d2, w2) = ours.sample_direction(it, sample), ref.sample_direction(it, sample)
        for name in ("p", "d", "dist", "uv", "pdf"):
            assert close(getattr(d1, name), getattr(d2, name), atol=1e-4), (sample, name)
        assert np.allclose(arr(w1), arr(w2), rtol=1e-4), sample
        assert (arr(w1) > 0).all()
    ds, _ = ours.sample_direction(it, [0.5, 0.5], True)
    assert arr(ds.pdf).min() > 0


def test_wavelengths_and_unimplemented_methods_behave_as_thinlens(variant):
    ours, ref = both()
    si = dr.zeros(mi.SurfaceInteraction3f)
    samples = [0.3] if variant.startswith("scalar") else [0.3, [0.1, 0.4, 0.9]]
    for s in samples:
        (l1, w1), (l2, w2) = ours.sample_wavelengths(si, s), ref.sample_wavelengths(si, s)
        assert close(w1, w2) and arr(l1).shape == arr(l2).shape
    # thinlens has no eval, pdf_direction or sample_position: neither has ours
    it = dr.zeros(mi.Interaction3f)
    it.p = mi.Point3f(11.0, 4.0, 1.5)
    ds, _ = ref.sample_direction(it, [0.5, 0.5])
    for call in (
        lambda c: c.eval(si),
        lambda c: c.pdf_direction(it, ds),
        lambda c: c.sample_position(0.0, [0.5, 0.5]),
    ):
        for cam in (ref, ours):
            with pytest.raises(RuntimeError):
                call(cam)


# ------------------------------------------------------------------------------------------
# 4. Clip planes, focus, field of view: accessors and mi.traverse
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("s_open, s_time", [(0.0, 0.0), (1.5, 3.0)])
def test_accessors(variant, s_open, s_time):
    for cam in both(shutter_open=s_open, shutter_close=s_open + s_time):
        assert cam.near_clip() == pytest.approx(1.0)
        assert cam.far_clip() == pytest.approx(35.0)
        assert dr.allclose(cam.focus_distance(), 15.0)
        assert cam.shutter_open() == pytest.approx(s_open)
        assert cam.shutter_open_time() == pytest.approx(s_time)
        assert cam.needs_aperture_sample()  # a thin lens needs an aperture sample
        m = look().matrix
        assert close(cam.world_transform().matrix, m)
    ours = both()[0]
    assert isinstance(ours.near_clip(), float) and isinstance(ours.focus_distance(), float)


def test_clip_planes_and_fov_are_traversable_like_thinlens(variant):
    ours, ref = both()
    p_ours, p_ref = mi.traverse(ours), mi.traverse(ref)
    for key in ("near_clip", "far_clip", "x_fov", "focus_distance", "to_world"):
        assert key in p_ours and key in p_ref, key
    for key, value in (("near_clip", 1.0), ("far_clip", 35.0), ("x_fov", 34.0)):
        assert dr.allclose(p_ours[key], value) and dr.allclose(p_ref[key], value), key
    for params in (p_ours, p_ref):
        params["x_fov"] = 50.0
        params["near_clip"] = 2.0
        params["far_clip"] = 20.0
        params.update()
    assert ours.near_clip() == pytest.approx(2.0) and ours.far_clip() == pytest.approx(20.0)
    fresh = mi.load_dict(camera("ours", fov=50.0, near_clip=2.0, far_clip=20.0))
    args = _samples(variant)[0]
    (r1, _), (r2, _), (r3, _) = (c.sample_ray(*args) for c in (ours, ref, fresh))
    for name in ("o", "d", "maxt"):
        assert close(getattr(r1, name), getattr(r2, name), atol=1e-4), name
        assert close(getattr(r1, name), getattr(r3, name), atol=1e-6), name
    # the fov reaches the edge of the film: a ray at the film's edge makes x_fov / 2
    ray, _ = ours.sample_ray(0, 0, [0.0, 0.5], [0.5, 0.5])
    angle = np.degrees(np.arccos(arr(dr.dot(ray.d, mi.Vector3f(DIRECTION)))))
    assert angle == pytest.approx(25.0, abs=1e-3)


@pytest.mark.render
def test_new_fov_or_clip_planes_do_not_recompile():
    """The projection's values are opaque: sweeping them through mi.traverse reuses the
    kernels (Mitsuba's own integrators bake a film crop in, for thinlens too)."""
    ok, why = llvm_status()
    if not ok:
        pytest.skip(f"LLVM backend unavailable: {why}")
    ac.register()
    scene = wall_scene("ours", "path", film())
    params = mi.traverse(scene)
    params["sensor.x_fov"] = 39.0  # the scene's first update may recompile once
    params.update()
    mi.render(scene, spp=2)
    for key, value in (("x_fov", 30.0), ("near_clip", 0.5), ("far_clip", 5000.0)):
        params["sensor." + key] = value
        params.update()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            mi.render(scene, spp=2)
            history = dr.kernel_history([dr.KernelType.JIT])
        assert history and all(h["cache_hit"] for h in history), key


@pytest.mark.parametrize(
    "key, value, match",
    [
        ("near_clip", 0.0, "near_clip"),
        ("near_clip", 40.0, "near_clip"),  # beyond far_clip (35)
        ("far_clip", 0.5, "near_clip"),  # before near_clip (1)
        ("x_fov", 180.0, "fov"),
        ("x_fov", -3.0, "fov"),
    ],
)
def test_bad_clip_or_fov_is_refused_and_changes_nothing(variant, key, value, match):
    ours = both()[0]
    before = ours.sample_ray(0, 0, [0.2, 0.7], [0.5, 0.5])[0]
    params = mi.traverse(ours)
    params[key] = value
    params["film.crop_size"] = [256, 128]  # the film applies its own change: follow it
    with pytest.raises(ParameterError, match=match):
        params.update()
    assert ours.near_clip() == pytest.approx(1.0) and ours.far_clip() == pytest.approx(35.0)
    assert dr.allclose(params[key], {"near_clip": 1.0, "far_clip": 35.0, "x_fov": 34.0}[key])
    cropped = mi.load_dict(camera("ours", film=film(512, 256, crop=((0, 0), (256, 128)))))
    r1, r2 = (c.sample_ray(0, 0, [0.2, 0.7], [0.5, 0.5])[0] for c in (ours, cropped))
    assert close(r1.d, r2.d, atol=1e-7)
    params["film.crop_size"] = [512, 256]
    params.update()
    after = ours.sample_ray(0, 0, [0.2, 0.7], [0.5, 0.5])[0]
    assert close(after.d, before.d, atol=1e-7) and close(after.o, before.o, atol=1e-7)


def test_bad_clip_planes_are_refused_at_load_time(variant):
    with pytest.raises(RuntimeError, match="near_clip"):
        mi.load_dict(camera("ours", near_clip=5.0, far_clip=2.0))
