"""Scenes: deterministic assets, the paper's layout and speeds, motion via traverse, errors,
tiny renders. Assets are built into a private cache; renders are 64 x 48 px."""

from __future__ import annotations

import hashlib
import json
import math
import warnings

import numpy as np
import pytest
import trimesh

from pacam_render import scenes as S
from pacam_render.errors import ParameterError
from pacam_render.model.camera import prototype
from pacam_render.scenes import assets as sa
from pacam_render.scenes import layout, meshes
from pacam_render.scenes.motion import _mi

W, H = 64, 48
F_PX = 0.5 * 1280 / math.tan(math.radians(23.0))  # independent of CameraDesign


@pytest.fixture(scope="module")
def mi():
    return _mi()


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    root = tmp_path_factory.mktemp("pacam_cache")
    sa.ensure_assets(root)
    return root


@pytest.fixture(scope="module")
def train(cache):
    return S.load_scene("train", cache_dir=cache)


def _sensor(spp: int = 4) -> dict:
    return {
        "type": "perspective",
        "fov": 46.0,
        "fov_axis": "x",
        "to_world": S.default_camera_to_world(),
        "film": {"type": "hdrfilm", "width": W, "height": H, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": spp},
    }


def _shape_bboxes(scene) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {
        s.id(): (np.array(s.bbox().min, float).ravel(), np.array(s.bbox().max, float).ravel())
        for s in scene.shapes()
    }


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- assets ------------------------------------------------------------------------------------
def test_assets_are_deterministic(cache, tmp_path):
    first = sa.asset_dir(cache)
    manifest = sa.build_assets(tmp_path / "again")
    assert manifest == sa.load_manifest(first)
    for name in manifest["files"]:
        assert _sha(first / name) == _sha(tmp_path / "again" / name), name


def test_closed_meshes_are_watertight_and_outward(cache):
    d = sa.asset_dir(cache)
    for name in meshes.CLOSED_MESHES:
        m = trimesh.load(d / f"{name}.ply", process=False)
        merged = trimesh.Trimesh(m.vertices, m.faces)  # merges the UV-seam duplicates
        assert merged.is_watertight and merged.is_winding_consistent, name
        assert merged.volume > 0, name  # outward normals: one-sided diffuse needs them
    for name, axis, sign in (("backdrop", 2, -1), ("soccer_wall", 2, -1), ("walker_floor", 1, 1)):
        m = trimesh.load(d / f"{name}.ply", process=False)
        assert np.allclose(m.face_normals[:, axis], sign), name  # facing the camera / up


# --- layout and speeds ---------------------------------------------------------------------------
def test_train_set_depths_from_loaded_scene(train, mi):
    bb = _shape_bboxes(train.load())
    for sid, z in (
        ("far_train", 500),
        ("far_track", 500),
        ("near_train", 495),
        ("near_track", 495),
        ("car", 490),
        ("backdrop", 505),
    ):
        assert bb[sid][0][2] == pytest.approx(z, abs=1e-4), sid
        assert bb[sid][1][2] <= 505.0, sid
    assert bb["backdrop"][1][2] == pytest.approx(505, abs=1e-4)
    half_w = 505 * math.tan(math.radians(23))  # the backdrop fills the 46 deg view
    assert -bb["backdrop"][0][0] > half_w and bb["backdrop"][1][0] > half_w
    assert -bb["backdrop"][0][1] > 0.75 * half_w and bb["backdrop"][1][1] > 0.75 * half_w
    assert bb["far_train"][0][1] > bb["near_train"][1][1]  # both trains visible


def test_ball_and_walker_depths(cache):
    ball = S.load_scene("soccer", cache_dir=cache).bboxes_mm["ball"]
    assert np.allclose((ball[0] + ball[1]) / 2, (0, 0, 1000), atol=1e-6)
    walker = S.load_scene("walker", cache_dir=cache)
    parts = [walker.bboxes_mm[k] for k in walker.moving_ids]
    lo, hi = np.min([p[0] for p in parts], 0), np.max([p[1] for p in parts], 0)
    assert (lo[2] + hi[2]) / 2 == pytest.approx(3000, abs=1)
    assert 1600 < hi[1] - lo[1] < 1800  # a person-sized proxy, feet on the floor
    assert 0 <= lo[1] - layout.WALKER_FLOOR_Y_MM < 5  # a toe on (not in) the floor


def test_train_speeds_in_prototype_pixels(train, cache):
    """Project a front-face vertex at two times with an independent pinhole."""
    dt = 10.0
    for sid, expected in (("far_train", 1.0), ("near_train", -1.4)):
        mesh = trimesh.load(sa.asset_dir(cache) / f"{sid}.ply", process=False)
        v = mesh.vertices[np.argmin(mesh.vertices[:, 2])]
        p0, p1 = v, train.motions[sid].apply(v[None], dt)[0]
        u0, u1 = (640 - F_PX * p[0] / p[2] for p in (p0, p1))
        assert (u1 - u0) / dt == pytest.approx(expected, rel=1e-9), sid  # + is rightwards
        assert p1[1] == p0[1] and p1[2] == p0[2]
    assert S.fastest_image_speed_px_per_ms(train, prototype()) == pytest.approx(1.4, rel=1e-9)


def test_other_scene_speeds(cache):
    cam = prototype()
    ball = S.load_scene("soccer", cache_dir=cache).motions["ball"]
    assert F_PX * -ball.velocity_mm_per_ms[0] / 1000 == pytest.approx(1.0)  # left to right
    walker = S.load_scene("walker", cache_dir=cache)
    assert walker.motions["walker_body"].velocity_mm_per_ms[0] == pytest.approx(1.4)  # to left
    fastest = S.fastest_image_speed_px_per_ms(walker, cam)
    assert 1.4 * F_PX / 3000 < fastest < 3.0  # swinging limbs outpace the body
    assert S.fastest_image_speed_px_per_ms(S.psf_scene(500.0), cam) == 0.0


def test_limb_keyframes_follow_the_gait(cache):
    leg = S.load_scene("walker", cache_dir=cache).motions["walker_leg_near"]
    t = 7.5  # between keyframes (5 ms apart)
    angle = layout.limb_angle_rad
    dtheta = angle("walker_leg_near", t) - angle("walker_leg_near", 0)
    m = leg.matrix_at(t)
    assert math.atan2(m[1, 0], m[0, 0]) == pytest.approx(dtheta, abs=1e-4)
    hip = np.array(layout.walker_pivots()["walker_leg_near"])
    assert np.allclose(leg.apply(hip[None], t)[0], hip + (1.4 * t, 0, 0))  # the hip rides along
    with pytest.raises(ParameterError, match="t_ms"):
        leg.matrix_at(1000.0)


# --- moving shapes ---------------------------------------------------------------------------
def test_traverse_moves_meshes_by_v_dt(train, mi):
    scene = train.load(_sensor())
    anim = train.animator(scene)
    before = _shape_bboxes(scene)
    assert anim.set_time(12.5) and anim.n_updates == 1
    after = _shape_bboxes(scene)
    for sid in ("far_train", "near_train"):
        shift = np.array(train.motions[sid].velocity_mm_per_ms) * 12.5
        assert np.allclose(after[sid][0] - before[sid][0], shift, atol=1e-3), sid
    assert np.allclose(after["backdrop"][0], before["backdrop"][0])
    assert not anim.set_time(12.5)  # same time: no BVH rebuild
    anim.set_time(0.0)
    assert np.allclose(_shape_bboxes(scene)["far_train"][0], before["far_train"][0], atol=1e-4)


def test_traverse_moves_to_world_and_keyframed_limbs(cache, mi):
    psf = S.psf_scene(800.0, velocity_mm_per_ms=(0.2, -0.1, 0.0), radius_mm=2.0)
    scene = psf.load(_sensor())
    psf.animator(scene).set_time(-20.0)
    lo, hi = _shape_bboxes(scene)["psf_disk"]
    assert np.allclose((lo + hi) / 2, (-4.0, 2.0, 800.0), atol=1e-4)
    walker = S.load_scene("walker", cache_dir=cache)
    scene = walker.load(_sensor())
    rest = np.array(mi.traverse(scene)["walker_leg_near.vertex_positions"]).reshape(-1, 3)
    walker.animator(scene).set_time(20.0)
    moved = np.array(mi.traverse(scene)["walker_leg_near.vertex_positions"]).reshape(-1, 3)
    expect = walker.motions["walker_leg_near"].apply(rest, 20.0)
    assert np.abs(moved - expect).max() < 1e-3  # mm


def test_static_scene_triggers_no_update(mi):
    psf = S.psf_scene(500.0)
    assert S.is_static(psf) and psf.moving_ids == []
    anim = psf.animator(psf.load(_sensor()))
    assert anim.set_time(10.0) is False and anim.n_updates == 0 and anim.params is None


# --- errors ------------------------------------------------------------------------------------
def test_errors(tmp_path, cache):
    with pytest.raises(ParameterError, match="soccer, train, walker"):
        S.load_scene("trian")
    with pytest.raises(ParameterError, match="not found"):
        S.load_scene(str(tmp_path / "missing.xml"))
    bad = tmp_path / "bad.xml"
    bad.write_text("<scene version='3.0.0'><shape type='ply'")
    with pytest.raises(ParameterError, match="does not load"):
        S.load_scene(str(bad))
    with pytest.raises(ParameterError, match="option"):
        S.load_scene("train", cache_dir=cache, warp_speed=9)
    with pytest.raises(ParameterError, match="depth_mm"):
        S.psf_scene(-1.0)
    with pytest.raises(ParameterError, match="far_speed_px_per_ms"):
        S.load_scene("train", cache_dir=cache, far_speed_px_per_ms=0.0)
    with pytest.raises(ParameterError, match="increasing"):
        S.Motion(keyframes=((1.0, np.eye(4)), (0.0, np.eye(4))))
    with pytest.raises(ParameterError, match="velocity_mm_per_ms"):
        S.Motion((math.nan, 0.0, 0.0))


def test_user_scene_file_with_motion(tmp_path, mi):
    xml = tmp_path / "mine.xml"
    xml.write_text(
        "<scene version='3.0.0'><sensor type='perspective'/>"
        "<shape type='sphere' id='ball'><point name='center' x='0' y='0' z='800'/>"
        "<float name='radius' value='10'/></shape></scene>"
    )
    motion = {"shapes": {"ball": {"velocity_mm_per_ms": [0.5, 0.0, 0.0]}}}
    (tmp_path / "mine.motion.json").write_text(json.dumps(motion))
    desc = S.load_scene(str(xml))
    assert desc.moving_ids == ["ball"] and "sensor" not in desc.scene_dict
    scene = desc.load(_sensor())  # no integrator in the file: the default path tracer
    desc.animator(scene).set_time(10.0)
    lo, hi = _shape_bboxes(scene)["ball"]
    assert np.allclose((lo + hi) / 2, (5.0, 0.0, 800.0), atol=1e-3)
    motion["shapes"]["nope"] = motion["shapes"].pop("ball")
    (tmp_path / "mine.motion.json").write_text(json.dumps(motion))
    with pytest.raises(ParameterError, match="nope"):
        S.load_scene(str(xml))


# --- renders, axes and XML ---------------------------------------------------------------------
@pytest.mark.parametrize("name", ["train", "soccer", "walker"])
def test_tiny_render(name, cache, mi):
    img = np.array(mi.render(S.load_scene(name, cache_dir=cache).load(_sensor()), seed=1))
    assert img.shape == (H, W, 3) and np.all(np.isfinite(img))
    assert img.mean() > 0.005 and img.std() > 0.005  # lit, and not a flat field


def test_psf_scene_black_except_disk_and_image_axes(mi):
    cam = prototype().with_(width_px=W, height_px=H)
    psf = S.psf_scene(500.0, radius_mm=8.0, offset_mm=(100.0, 0.0), camera=cam)
    img = np.array(mi.render(psf.load(_sensor(16)), seed=3))[..., 0]
    u0, v0 = S.project_px((100.0, 0.0, 500.0), cam)
    assert u0 < W / 2  # world +x lands on the image's left
    rows, cols = np.mgrid[0:H, 0:W] + 0.5
    far = np.hypot(cols - u0, rows - v0) > psf.info["radius_px"] + 1.5
    assert np.all(img[far] == 0) and img.sum() == pytest.approx(1.0, rel=0.1)
    assert (img * cols).sum() / img.sum() == pytest.approx(u0, abs=0.3)
    assert (img * rows).sum() / img.sum() == pytest.approx(v0, abs=0.3)


def test_camera_pose_and_look_at(mi):
    assert np.allclose(np.array(S.default_camera_to_world().matrix), np.eye(4))
    ref = mi.ScalarTransform4f().look_at(origin=[190, 230, 120], target=[0, 0, 500], up=[0, 1, 0])
    assert np.allclose(S.look_at((190, 230, 120), (0, 0, 500)), np.array(ref.matrix), atol=1e-6)


@pytest.mark.parametrize("name", ["train", "soccer", "walker"])
def test_committed_scene_files_match_and_load(name, cache, mi):
    desc = S.load_scene(name, cache_dir=cache)
    xml, motion = S.SCENE_DIR / f"{name}.xml", S.SCENE_DIR / f"{name}.motion.json"
    assert xml.read_text() == S.scene_to_xml(desc, sa.asset_dir(cache))
    assert motion.read_text() == S.motion_to_json(desc)
    loaded = S.load_scene(str(xml), cache_dir=cache)
    for sid, (lo, hi) in desc.bboxes_mm.items():
        assert np.allclose(loaded.bboxes_mm[sid], (lo, hi), atol=1e-3), sid
    assert loaded.moving_ids == desc.moving_ids
    for sid in desc.moving_ids:
        assert np.allclose(loaded.motions[sid].matrix_at(3.0), desc.motions[sid].matrix_at(3.0))


# --- user scenes fail loudly (issue 27, trap 3) --------------------------------------------------
def _user_scene(folder, motion: dict | None = None, scale: float = 1.0):
    """A ball and a wall of a user's file, in metres (scale 1: the ball's front 0.5 units from
    the camera) or in mm (scale 1000); its motion file if ``motion`` is given."""
    xml = folder / "mine.xml"
    xml.write_text(
        "<scene version='3.0.0'>"
        f"<shape type='sphere' id='ball'><point name='center' x='0' y='0' z='{1.0 * scale}'/>"
        f"<float name='radius' value='{0.5 * scale}'/></shape>"
        "<shape type='rectangle' id='wall'><transform name='to_world'>"
        f"<scale value='{2.0 * scale}'/><translate z='{3.0 * scale}'/></transform></shape>"
        "<emitter type='constant'/></scene>"
    )
    if motion is not None:
        (folder / "mine.motion.json").write_text(json.dumps(motion))
    return xml


def test_motion_file_keys_are_checked(tmp_path):
    cases = [  # (motion file, what the message names)
        ({"shapes": {"ball": {"velocity": [0.3, 0, 0]}}}, "'velocity'.*velocity_mm_per_ms"),
        ({"shape": {"ball": {}}}, "'shape'.*valid keys: shapes, depths_mm"),
        ({"shapes": {"bal": {}}}, "'bal'.*no shape of the scene.*shape ids: ball, wall"),
        ({"shapes": {}, "depths_mm": {"ball": "500"}}, "depths_mm of 'ball' must be a number"),
        ({"shapes": {"ball": {"keyframes": [{"t": 0, "matrix": []}]}}}, "'t'.*t_ms, matrix"),
        ({"depths_mm": {}}, "lacks the key 'shapes'"),
        ({"shapes": {"ball": [0.3, 0, 0]}}, "shape 'ball' must be a JSON object"),
    ]
    for motion, message in cases:
        xml = _user_scene(tmp_path, motion)
        with pytest.raises(ParameterError, match=message):
            S.load_scene(str(xml))
    good = {"shapes": {"ball": {"velocity_mm_per_ms": [0.3, 0, 0]}}, "depths_mm": {"ball": 0.5}}
    assert S.load_scene(str(_user_scene(tmp_path, good))).moving_ids == ["ball"]


def test_cli_render_refuses_a_misspelt_motion_key(tmp_path, capsys):
    from pacam_render.cli import main

    xml = _user_scene(tmp_path, {"shapes": {"ball": {"velocity": [0.3, 0, 0]}}}, 1000.0)
    args = ["render", str(xml), "--width", "16", "--height", "12", "--spp", "4", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "unknown key 'velocity'" in err and "velocity_mm_per_ms" in err
    assert not (tmp_path / "out" / "capture.exr").exists()


def test_a_scene_file_without_motion_is_noted_static(tmp_path):
    from pacam_render.limits import PacamWarning

    with pytest.warns(PacamWarning, match=r"mine.xml is static: no mine.motion.json .*README") as w:
        S.load_scene(str(_user_scene(tmp_path, scale=1000.0)))
    assert sum("is static" in str(r.message) for r in w) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)  # a motion file, even a still one: no note
        S.load_scene(str(_user_scene(tmp_path, {"shapes": {}}, 1000.0)))


@pytest.mark.render
def test_a_scene_in_metres_gets_a_note_naming_millimetres(tmp_path, capsys):
    from pacam_render.cli import main

    xml = _user_scene(tmp_path, {"shapes": {}})
    args = ["render", str(xml), "--width", "16", "--height", "12", "--spp", "4", "--quiet"]
    assert main([*args, "--mode", "normal", "--out", str(tmp_path / "out")]) == 0
    notes = json.loads((tmp_path / "out" / "capture.json").read_text())["notes"]
    (note,) = [n for n in notes if "metres" in n]
    assert note.startswith("the nearest surface is 0.5 mm from the camera")
    assert "pacam scenes are in mm" in note and "4 mm across" in note
    assert f"note: {note}" in capsys.readouterr().err


@pytest.mark.render
def test_units_check_spares_scenes_in_mm(tmp_path, cache, mi):
    from pacam_render.exposure.camera import capture_design
    from pacam_render.exposure.spec import CaptureSpec
    from pacam_render.scenes.units import units_note

    design = capture_design(CaptureSpec.geometric(width=W, height=H))
    user = S.load_scene(str(_user_scene(tmp_path, {"shapes": {}}, 1000.0)))
    (tmp_path / "m").mkdir()
    metres = S.load_scene(str(_user_scene(tmp_path / "m", {"shapes": {}})))
    scenes = [S.load_scene(n, cache_dir=cache) for n in ("train", "soccer", "walker")]
    for desc in [*scenes, S.psf_scene(500.0), user]:
        assert units_note(desc.load(), design) is None, desc.name
    assert "in metres?" in units_note(metres.load(), design)
