"""Whole-scene validation (``pacam validate-scene``): the two-dimensional PSF against the exact
one-dimensional kernel and its transpose, the regions against a layout drawn by hand, and the
convolution model against ray tracing on two scenes with known answers:

* a textured plane at one depth, moving at one speed, filling the view: the model is right
  everywhere, so every scored region must be at the Monte Carlo floor;
* a moving plane in front of a still one: the model must hold in both interiors and fail only
  in the band around the occluding edge.
"""

import json

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.experiments import validate_scene as vs
from pacam_render.experiments.scene_error import _stats
from pacam_render.experiments.scene_regions import REGIONS, region_map
from pacam_render.model.camera import prototype
from pacam_render.psf.analytic import design_psf, design_trajectory
from pacam_render.psf.planar import planar_kernel
from pacam_render.psf.scene import build_cells
from pacam_render.scenes.description import SceneDescription
from pacam_render.scenes.motion import Motion, image_to_scene_velocity


def _centred(k: np.ndarray, shape) -> np.ndarray:
    out = np.zeros(shape)
    i, j = (shape[0] - k.shape[0]) // 2, (shape[1] - k.shape[1]) // 2
    out[i : i + k.shape[0], j : j + k.shape[1]] = k
    return out


@pytest.mark.parametrize("mode", ["coded", "coded_continuous", "normal", "flutter", "levin"])
def test_planar_kernel_without_vertical_speed_is_the_exact_kernel(mode):
    cam = prototype()
    segments, r = design_trajectory(cam, mode, 0.6, "pinhole")
    exact = design_psf(cam, mode, 0.6, origin="pinhole")
    quad = planar_kernel(segments, r, 0.0)
    assert quad.shape[1] == exact.shape[1]
    # midpoint rule at 0.05 px; levin's in-focus point is binned (first order) at 0.002 px
    assert np.abs(_centred(quad, exact.shape) - exact).sum() < (1e-3 if r == 0 else 1e-4)


def test_a_vertical_path_is_the_transposed_horizontal_kernel():
    cam = prototype()
    segments, r = design_trajectory(cam, "normal", 0.0)
    vertical = planar_kernel(segments, r, 0.7)
    horizontal = design_psf(cam, "normal", 0.7).T
    n = max(vertical.shape + horizontal.shape)
    assert np.abs(_centred(vertical, (n, n)) - _centred(horizontal, (n, n))).sum() < 1e-4


def test_planar_kernel_refuses_bad_input():
    segments, r = design_trajectory(prototype(), "coded", 0.0)
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ParameterError, match="v_px_per_ms"):
            planar_kernel(segments, r, bad)
    with pytest.raises(ParameterError, match="step_px"):
        planar_kernel(segments, r, 0.1, step_px=0.0)


def test_a_region_without_noise_is_at_the_floor_only_if_exact():
    zero = np.zeros((4, 4, 3))
    exact = _stats(zero, zero, 16)
    assert exact["ratio"] == 1.0 and exact["at_floor"]
    off = _stats(zero + 0.1, zero, 16)
    assert off["ratio"] == float("inf") and not off["at_floor"]


def test_cells_quantise_velocity_and_depth():
    """Pixels a hundredth of a quantum apart share a cell; a quantum apart do not."""
    cam = prototype().with_(width_px=1280)
    depth = np.full((4, 4), 600.0)
    velocity = np.zeros((4, 4, 2))
    velocity[:, :2, 0] = 0.5
    velocity[0, 0, 0] = 0.5 + 0.01 * 0.25 / cam.T_ms
    velocity[:, 3, 0] = 0.5 + 1.0 / cam.T_ms  # one whole px further over T
    layers = {"depth": depth, "object_id": np.ones((4, 4)), "velocity": velocity}
    cells = build_cells(layers, cam, "coded", 0.25)
    assert sorted(c.rows.size for c in cells) == [4, 4, 8]
    still = [c for c in cells if not c.moving]
    assert len(still) == 1 and still[0].kernel.sum() == pytest.approx(1.0)


def test_regions_of_a_drawn_layout():
    """A moving square on a still background: bands of the given widths around its edge."""
    ids = np.ones((60, 80))
    ids[20:40, 30:50] = 2
    velocity = np.zeros((60, 80, 2))
    velocity[ids == 2, 0] = 0.5
    reg = region_map(ids, np.zeros((60, 80)), velocity, 6.0, 3.0, 4.0)
    name = np.array(REGIONS)[reg]
    assert (name[:4] == "frame").all() and (name[:, -4:] == "frame").all()
    assert name[30, 40] == "moving_interior"  # 10 px from the edge
    assert name[30, 33] == "moving_edge_band"  # 3 px inside
    assert name[30, 26] == "background_near_moving"  # 4 px outside
    assert name[30, 20] == "still_interior"  # 10 px outside
    assert not (name == "still_edge_band").any()  # no edge between still surfaces


# --- ray tracing against the model ------------------------------------------------------------

CROP = (616, 456, 48, 40)  # a window at the centre of the prototype's 1280x960 sensor
SPEED = 0.5  # px/ms, inside the prototype's invariant range (0.9 px/ms)


def _plane(half: float, z: float, texture: str, x: float = 0.0) -> dict:
    m = np.diag([-half, half, -1.0, 1.0])  # 180 deg about y: the face looks at the camera
    m[:3, 3] = (x, 0.0, z)
    tex = {"type": "bitmap", "filename": texture, "filter_type": "bilinear"}
    return {"type": "rectangle", "to_world": m, "bsdf": {"type": "diffuse", "reflectance": tex}}


def _texture(path, seed: int, lo: float, hi: float) -> str:
    """A smooth random texture (features of about 10 px at 600 mm) from lo to hi, as a PNG."""
    import matplotlib.pyplot as plt
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    img = gaussian_filter(rng.random((128, 128)), 1.5, mode="wrap")
    img = (img - img.min()) / (img.max() - img.min())
    plt.imsave(path, lo + (hi - lo) * img, cmap="gray", vmin=0, vmax=1)
    return str(path)


def _scene(tmp_path, occluded: bool) -> SceneDescription:
    v = image_to_scene_velocity(SPEED, 600.0, prototype())
    shapes = {"sky": {"type": "constant"}}
    front = _texture(tmp_path / "f.png", 2, 0.05, 0.3)
    if occluded:  # a dark plane's left edge crosses the middle column; bright behind
        shapes["back"] = _plane(500.0, 900.0, _texture(tmp_path / "b.png", 1, 0.5, 0.9))
        shapes["front"] = _plane(150.0, 600.0, front, x=-150.0)
    else:
        shapes["front"] = _plane(500.0, 600.0, front)
    box = (np.array([-300.0, -150.0, 600.0]), np.array([0.0, 150.0, 600.0]))
    return SceneDescription(
        name="planes",
        scene_dict={"type": "scene", **shapes},
        motions={"front": Motion(tuple(v))},
        bboxes_mm={"front": box},
        depths_mm={"front": 600.0, "back": 900.0},
        integrator={"type": "direct"},
    )


def _validate(tmp_path, occluded: bool, crop=CROP, **optics) -> dict:
    check = vs.SceneCheck(scene="planes", crop=crop, spp=32, seed=5, **optics)
    out = tmp_path / "out"
    s = vs.run(check, out, progress=False, description=_scene(tmp_path, occluded))
    if optics:
        assert s["optics"]["flat_fielded"] == (optics["relative_illumination"] != "off")
        assert s["optics"]["model_diffracted"] == (optics["diffraction"] == "on")
    assert {"validate_scene.csv", "validate_scene.png", "validate_scene.md"} <= set(s["files"])
    assert json.loads((out / "validate_scene.json").read_text())["cells"] == s["cells"]
    return {(r["model"], r["region"]): r for r in s["rows"]}


@pytest.mark.render
def test_one_moving_plane_agrees_with_the_model_at_the_noise_floor(tmp_path):
    rows = _validate(tmp_path, occluded=False)
    assert {region for _, region in rows} == {"moving_interior", "all"}  # no edge in view
    for model in vs.MODELS:
        r = rows[model, "moving_interior"]
        assert r["pixels"] == CROP[2] * CROP[3]
        assert r["at_floor"], r
        assert 0.9 < r["ratio"] < 1.1


@pytest.mark.render
def test_with_a_cameras_optics_the_comparison_is_like_with_like(tmp_path):
    """A corner window (cos^4 = 0.62 there), the capture's diffraction in the rays: the
    flat-fielded capture agrees with the diffracted model at the noise floor. Without the flat
    field the interior would be off by 38 % of its signal, thousands of noise sigmas."""
    optics = {"relative_illumination": "cos4", "diffraction": "on"}
    rows = _validate(tmp_path, occluded=False, crop=(8, 8, 48, 40), **optics)
    for model in vs.MODELS:
        r = rows[model, "moving_interior"]
        assert r["at_floor"], r
        assert 0.9 < r["ratio"] < 1.1


@pytest.mark.render
def test_occluding_planes_disagree_only_in_the_edge_band(tmp_path):
    rows = _validate(tmp_path, occluded=True)
    for model in vs.MODELS:
        for name in ("moving_interior", "still_interior"):
            assert rows[model, name]["at_floor"], rows[model, name]
        band = [rows[model, n] for n in ("moving_edge_band", "background_near_moving")]
        assert max(r["ratio"] for r in band) > 2.5
        assert not any(r["at_floor"] for r in band)


def test_cli_refuses_bad_input_before_rendering(tmp_path, capsys):
    from pacam_render.cli import main

    out = str(tmp_path / "v")
    assert main(["validate-scene", "soccer", "--quantum", "0", "--out", out]) == 2
    assert "--quantum" in capsys.readouterr().err
    assert main(["validate-scene", "nope", "--out", out]) == 2
    assert "nope" in capsys.readouterr().err
    assert main(["validate-scene", "soccer", "--crop", "0,0,5", "--out", out]) == 2
    assert "--crop" in capsys.readouterr().err
    assert main(["validate-scene", "soccer", "--spp", "0", "--out", out]) == 2
    assert "spp" in capsys.readouterr().err
    assert main(["validate-scene", "soccer", "--speed", "-1", "--out", out]) == 2
    assert "--speed" in capsys.readouterr().err
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "validate_scene.csv").write_text("keep")
    assert main(["validate-scene", "soccer", "--out", out]) == 2
    assert "--force" in capsys.readouterr().err
    assert (tmp_path / "v" / "validate_scene.csv").read_text() == "keep"
    with pytest.raises(SystemExit):
        main(["validate-scene", "soccer", "--mode", "levin", "--out", out])


@pytest.mark.render
def test_cli_quick_writes_the_report(tmp_path, capsys):
    from pacam_render.cli import main

    out = tmp_path / "q"
    assert main(["validate-scene", "soccer", "--quick", "--quiet", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "moving interior (" in said and "error/noise" in said
    md = (out / "validate_scene.md").read_text()
    assert "| background_near_moving |" in md and "160x128 px window" in md
    rows = list(__import__("csv").DictReader(open(out / "validate_scene.csv")))
    assert {r["model"] for r in rows} == {"composite", "layered"}
