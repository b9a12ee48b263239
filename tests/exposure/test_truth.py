"""Ground-truth layers (``sharp``, ``depth``, ``object_id``, ``velocity``) against a scene whose
answers are known in closed form: two fronto-parallel squares at known depths, one moving at a
known image velocity, and empty sky around them."""

import json
import subprocess
import sys

import numpy as np
import pytest

from pacam_render.exposure.camera import capture_design
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.exposure.truth import TRUTH_LAYERS
from pacam_render.io.exr import read_exr, write_exr
from pacam_render.scenes.description import SceneDescription
from pacam_render.scenes.motion import Motion, image_to_scene_velocity, project_px

pytestmark = pytest.mark.render

W, H = 64, 48
BACK_Z, FRONT_Z = 900.0, 600.0
BACK_HALF, FRONT_HALF = 60.0, 25.0  # mm: both squares leave sky around them
V_IMG = (0.75, -0.25)  # px/ms of the 64-px capture


def _square(half: float, z: float, x: float = 0.0) -> dict:
    m = np.diag([-half, half, -1.0, 1.0])  # 180 deg about y: the face looks at the camera
    m[:3, 3] = (x, 0.0, z)
    return {"type": "rectangle", "to_world": m, "bsdf": {"type": "diffuse"}}


def _scene() -> SceneDescription:
    design = capture_design(CaptureSpec.geometric(width=W, height=H))
    v = image_to_scene_velocity(V_IMG, FRONT_Z, design)
    box = (
        np.array([-FRONT_HALF, -FRONT_HALF, FRONT_Z]),
        np.array([FRONT_HALF, FRONT_HALF, FRONT_Z]),
    )
    return SceneDescription(
        name="squares",
        scene_dict={
            "type": "scene",
            "back": _square(BACK_HALF, BACK_Z, x=10.0),
            "front": _square(FRONT_HALF, FRONT_Z),
            "sky": {"type": "constant"},
        },
        motions={"front": Motion(tuple(v))},
        bboxes_mm={"front": box},
        integrator={"type": "direct"},
    )


@pytest.fixture(scope="module")
def coded():
    spec = CaptureSpec.geometric(mode="normal", width=W, height=H, spp=16, seed=3)
    return spec, render_capture(spec, progress=False, description=_scene())


def _ids(cap) -> dict[str, np.ndarray]:
    ids = cap.extra_layers["object_id"]
    return {name: ids == int(k) for k, name in cap.record.objects.items()}


def test_layers_and_legend(coded):
    _, cap = coded
    assert list(cap.extra_layers) == list(TRUTH_LAYERS)
    assert sorted(cap.record.objects.values()) == ["back", "front"]
    ids = cap.extra_layers["object_id"]
    assert set(np.unique(ids)) == {0.0, 1.0, 2.0}  # sky, back, front: integers only
    assert cap.meta["objects"] == cap.record.objects


def test_object_mask_is_the_projected_square(coded):
    spec, cap = coded
    design = capture_design(spec)
    corners = np.array([[-FRONT_HALF, -FRONT_HALF, FRONT_Z], [FRONT_HALF, FRONT_HALF, FRONT_Z]])
    (u0, v0), (u1, v1) = np.sort(project_px(corners, design), axis=0)
    cols, rows = np.arange(W) + 0.5, np.arange(H) + 0.5  # pixel centres
    inside = ((rows > v0) & (rows < v1))[:, None] & ((cols > u0) & (cols < u1))[None, :]
    assert np.array_equal(_ids(cap)["front"], inside)


def test_depth_is_each_planes_z(coded):
    _, cap = coded
    depth, masks = cap.extra_layers["depth"], _ids(cap)
    np.testing.assert_allclose(depth[masks["front"]], FRONT_Z, rtol=1e-6)
    np.testing.assert_allclose(depth[masks["back"]], BACK_Z, rtol=1e-6)
    sky = cap.extra_layers["object_id"] == 0
    assert sky.any() and np.all(depth[sky] == 0)


def test_velocity_is_the_shapes_image_speed(coded):
    _, cap = coded
    vel, masks = cap.extra_layers["velocity"], _ids(cap)
    np.testing.assert_allclose(
        vel[masks["front"]], np.broadcast_to(V_IMG, (masks["front"].sum(), 2)), atol=1e-6
    )
    assert np.all(vel[~masks["front"]] == 0)


def test_sharp_is_the_reference_capture_bit_for_bit(coded):
    spec, cap = coded
    ref = CaptureSpec.geometric(mode="reference", width=W, height=H, spp=16, seed=3)
    image = render_capture(ref, progress=False, description=_scene(), truth=False).image
    assert np.array_equal(cap.extra_layers["sharp"], image)
    assert not np.array_equal(cap.image, image)  # the capture itself is blurred


def test_a_crop_holds_the_same_window_of_every_layer(coded):
    spec, cap = coded
    x, y, w, h = 20, 10, 24, 20
    spec_c = CaptureSpec.geometric(
        mode="normal", width=W, height=H, spp=16, seed=3, crop=(x, y, w, h)
    )
    cropped = render_capture(spec_c, progress=False, description=_scene())
    for name in ("depth", "object_id", "velocity"):
        np.testing.assert_allclose(
            cropped.extra_layers[name],
            cap.extra_layers[name][y : y + h, x : x + w],
            rtol=1e-6,  # float32 positions
            atol=1e-6,
        )


def test_exr_round_trips_a_two_channel_layer(tmp_path):
    vel = np.random.default_rng(0).normal(size=(5, 7, 2)).astype(np.float32)
    write_exr(tmp_path / "v.exr", {"velocity": vel, "object_id": np.ones((5, 7))})
    back = read_exr(tmp_path / "v.exr")
    assert np.array_equal(back["velocity"], vel) and back["object_id"].shape == (5, 7)


def test_cli_writes_the_layers_and_no_truth_leaves_them_out(tmp_path):
    def run(out, *extra):
        cmd = [sys.executable, "-m", "pacam_render", "render", "train", "--width", "32"]
        cmd += ["--height", "24", "--spp", "4", "--mode", "normal", "--quiet", "--out", str(out)]
        return subprocess.run(cmd + list(extra), capture_output=True, text=True, check=True)

    run(tmp_path / "a")
    layers = read_exr(tmp_path / "a" / "capture.exr")
    assert set(TRUTH_LAYERS) <= set(layers)
    legend = json.loads((tmp_path / "a" / "capture.json").read_text())["objects"]
    assert "near_train" in legend.values()
    # The trains' image speeds in the 32-px image: 1.0 and -1.4 px/ms at 1280 px on their
    # camera-facing sides (the median pixel); their tops lie a little deeper, so a little slower.
    for name, speed in (("far_train", 1.0), ("near_train", -1.4)):
        (key,) = [k for k, v in legend.items() if v == name]
        u = layers["velocity"][..., 0][layers["object_id"] == int(key)]
        np.testing.assert_allclose(np.median(u), speed * 32 / 1280, rtol=1e-5)
        np.testing.assert_allclose(u, speed * 32 / 1280, rtol=0.01)
    run(tmp_path / "b", "--no-truth")
    # the cos^4 map stays: it is the camera's, not the scene's truth, and readers flat-field
    assert set(read_exr(tmp_path / "b" / "capture.exr")) == {"capture", "relative_illumination"}
    assert "objects" not in json.loads((tmp_path / "b" / "capture.json").read_text())


def test_design_fit_states_each_objects_defocus_and_speed(coded):
    """The record's ``design_fit`` against the thin lens (Eqs. 9, 12): a normal capture focuses
    on the design depth, so a plane at z has r = |1/Z_d - 1/z| f_px R; the front square's speed
    is |V_IMG|. An object whose r is 0.5 px and 20 % off the design's is noted."""
    spec, cap = coded
    cam = capture_design(spec)
    fit = cap.record.design_fit
    for name, z in (("back", BACK_Z), ("front", FRONT_Z)):
        r = abs(1 / cam.object_depth_mm - 1 / z) * cam.focal_length_px * cam.R_mm
        assert fit[name]["depth_mm"] == pytest.approx(z, rel=1e-3)
        assert fit[name]["r_px"] == pytest.approx(r, rel=1e-3)
        assert fit[name]["off_depth"] == (r > 0.5)
        assert "range_px_per_ms" not in fit[name]  # a normal camera has no invariant range
        noted = any(f"object {name!r} lies at" in n for n in cap.record.notes)
        assert noted == fit[name]["off_depth"]
    assert fit["front"]["speed_px_per_ms"] == pytest.approx(np.hypot(*V_IMG), rel=1e-3)
    assert fit["back"]["speed_px_per_ms"] == 0.0
    assert json.loads(json.dumps(cap.meta["design_fit"])) == fit


def test_design_fit_range_scales_with_beta_and_flags_fast_objects():
    """A coded camera's invariant range at depth z is |a_i(z)| T, with a_i proportional to
    beta(z) (Eq. 18): half the design's beta, half the range. Levin's body motion keeps its
    range at every depth. Synthetic layers: object 1 at the design depth, object 2 where beta
    is half of it, each moving just above its own range."""
    from pacam_render.exposure.design_fit import fit_notes, object_fit
    from pacam_render.model.camera import preset

    cam = preset("prototype")
    zd, zf = cam.object_depth_mm, cam.focus_distance_mm
    z2 = 1 / (1 / zf - 0.5 * (1 / zf - 1 / zd))  # beta(z2) = beta(zd) / 2
    rng = cam.velocity_range_px_per_ms
    ids = np.repeat([[1, 2]], 4, axis=0)
    depth = np.where(ids == 1, zd, z2)
    vel = np.zeros(ids.shape + (2,))
    vel[..., 0] = np.where(ids == 1, 1.01 * rng, 0.99 * rng)
    layers = {"object_id": ids, "depth": depth, "velocity": vel}
    fit = object_fit(layers, {"1": "a", "2": "b"}, cam, "coded")
    assert fit["a"]["range_px_per_ms"] == pytest.approx(rng)
    assert fit["b"]["range_px_per_ms"] == pytest.approx(0.5 * rng)
    assert fit["a"]["too_fast"] and fit["b"]["too_fast"]
    assert fit["b"]["r_px"] == pytest.approx(0.5 * cam.r_px) and fit["b"]["off_depth"]
    assert len(fit_notes(fit, cam, "coded")) == 3  # a too fast; b off its depth and too fast
    levin = object_fit(layers, {"1": "a", "2": "b"}, cam, "levin")
    assert levin["b"]["range_px_per_ms"] == pytest.approx(rng) and not levin["b"]["too_fast"]
    assert levin["a"]["r_px"] == pytest.approx(0.0, abs=1e-9)  # Levin's lens is on the object


def test_an_interrupted_capture_leaves_a_scene_file_s_meshes_at_t_0(tmp_path):
    """A scene file's description shares its mesh objects with every scene it loads
    (``load_scene_file``): a capture stopped mid-exposure must put them back at t = 0
    (``SceneAnimator``'s exit), or the next scene loaded from it (a truth render, a store's)
    shows the objects where the stop left them. Reference: the same file loaded afresh."""

    import mitsuba as mi

    from pacam_render.exposure.integrate import CaptureInterrupted
    from pacam_render.scenes import load_scene

    spec = CaptureSpec.geometric(scene="family:occluders:0", width=1280, height=960, grey=True,
                                 crop=(661, 449, 64, 32), spp=4, passes=2, seed=1)  # fmt: skip
    desc = load_scene(spec.scene)

    def meshes(d):
        p = mi.traverse(d.load())
        return {k: np.array(p[k]) for k in p.keys() if k.endswith("vertex_positions")}

    with pytest.raises(CaptureInterrupted):
        render_capture(spec, progress=False, description=desc,
                       stop_after_steps=3, partial_dir=tmp_path / "partial")  # fmt: skip
    got, fresh = meshes(desc), meshes(load_scene(spec.scene))
    moving = [k for k in got if k.split(".")[0] in desc.moving_ids]
    assert moving, list(got)
    for k in moving:
        np.testing.assert_allclose(got[k], fresh[k], atol=1e-4, err_msg=k)
