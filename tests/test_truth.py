"""Ground-truth layers (``sharp``, ``depth``, ``object_id``, ``velocity``) against a scene whose
answers are known in closed form: two fronto-parallel squares at known depths, one moving at a
known image velocity, and empty sky around them."""

import json
import subprocess
import sys

import numpy as np
import pytest

from pacam_render.exposure.capture import CaptureSpec, capture_design, render_capture
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
    design = capture_design(CaptureSpec(width=W, height=H))
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
    spec = CaptureSpec(mode="normal", width=W, height=H, spp=16, seed=3)
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
    ref = CaptureSpec(mode="reference", width=W, height=H, spp=16, seed=3)
    image = render_capture(ref, progress=False, description=_scene(), truth=False).image
    assert np.array_equal(cap.extra_layers["sharp"], image)
    assert not np.array_equal(cap.image, image)  # the capture itself is blurred


def test_a_crop_holds_the_same_window_of_every_layer(coded):
    spec, cap = coded
    x, y, w, h = 20, 10, 24, 20
    spec_c = CaptureSpec(mode="normal", width=W, height=H, spp=16, seed=3, crop=(x, y, w, h))
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
    assert set(read_exr(tmp_path / "b" / "capture.exr")) == {"capture"}
    assert "objects" not in json.loads((tmp_path / "b" / "capture.json").read_text())
