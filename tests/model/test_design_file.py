"""The camera design as one object and one file: design files, their round trips and their
errors; the design's digest; a bitmap schedule held whole (issue 35 item 1).

References: the design's own closed forms (Eq. 12: r = |beta| R; the paper's F-number scale
N = N_min R_max / R), the prototype preset, and equality of the rebuilt objects.
"""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.camera import CameraDesign, preset
from pacam_render.model.design_file import (
    design_toml,
    read_design,
    resolve_design,
    write_design,
)
from pacam_render.model.masks import MaskStack, disc_masks
from pacam_render.model.modes import sensor_params

MINIMAL = """
[lens]
focus_distance_mm = {focus!r}
[opening]
{opening}
[schedule]
kind = "parabolic"
"""


def _minimal(tmp_path, opening: str, focus: float | None = None):
    focus = preset("prototype").focus_distance_mm if focus is None else focus
    p = tmp_path / "d.toml"
    p.write_text(MINIMAL.format(focus=focus, opening=opening))
    return p


@pytest.mark.parametrize("key", ["R_mm", "F_number", "r_px"])
def test_the_opening_by_R_F_number_or_r_gives_the_prototype(tmp_path, key):
    proto = preset("prototype")
    name = {"F_number": "f_number"}.get(key, key)
    d = read_design(_minimal(tmp_path, f"{name} = {getattr(proto, key)!r}"))
    assert d.R_mm == pytest.approx(proto.R_mm, rel=1e-6)
    assert d.r_px == pytest.approx(2.0, rel=1e-6)  # Eq. 12 at 500 mm
    assert d.F_number == pytest.approx(proto.F_number, rel=1e-6)
    assert d.n_patterns == 16 and d.exposure_ms == 45.0


def _bitmap_design(tmp_path) -> CameraDesign:
    proto = preset("prototype")
    c = proto.pattern_centres_xy_mm()[::2]  # 8 of the parabola's openings
    masks = disc_masks(-c, proto.R_mm)  # disc_masks takes the plugin's local frame: (-x, -y)
    np.save(tmp_path / "m.npy", masks)
    stack = MaskStack(masks, source="m.npy")
    return proto.with_(
        pattern_masks=stack, n_patterns=8, R_mm=stack.equivalent_radius_mm(), name="bitmaps"
    )


def test_every_schedule_kind_round_trips_exactly_through_a_file(tmp_path):
    proto = preset("prototype")
    centres = proto.with_(
        pattern_centres_mm=tuple(map(tuple, proto.pattern_centres_xy_mm()[::2])), n_patterns=8
    )
    fast = proto.with_(n_patterns=32, exposure_ms=30.0, lcos_rate_fps=1200.0)
    for cam in (proto, centres, fast, _bitmap_design(tmp_path), proto.with_(sensor_preset="paper")):
        path = tmp_path / f"{cam.digest()}.toml"
        write_design(path, cam)
        back = read_design(path)
        assert back.digest() == cam.digest()
        assert back.with_(name=cam.name) == cam


def test_a_bitmap_design_is_written_with_its_masks_and_refused_over_itself(tmp_path):
    cam = _bitmap_design(tmp_path)
    files = write_design(tmp_path / "b.toml", cam)
    assert [f.name for f in files] == ["b.toml", "b.masks.npz"]
    assert 'masks = "b.masks.npz"' in (tmp_path / "b.toml").read_text()
    assert (tmp_path / "b.masks.npz").stat().st_size < 50_000  # 8 x 1024 x 1280, compressed
    with pytest.raises(ParameterError, match="force"):
        write_design(tmp_path / "b.toml", cam)
    write_design(tmp_path / "b.toml", cam, force=True)


def test_inputs_hold_the_bitmaps_whole_and_survive_json_and_pickle(tmp_path):
    cam = _bitmap_design(tmp_path)
    d = json.loads(json.dumps(cam.inputs()))
    assert CameraDesign.from_inputs(d) == cam
    assert pickle.loads(pickle.dumps(cam)) == cam
    d["pattern_masks"]["digest"] = "0" * 16  # an edited record is refused
    with pytest.raises(ParameterError, match="digest"):
        CameraDesign.from_inputs(d)


def test_the_digest_changes_with_every_input_but_the_name():
    proto = preset("prototype")
    assert proto.with_(name="x").digest() == proto.digest()
    for change in (
        {"R_mm": proto.R_mm * 1.01},
        {"n_patterns": 15},
        {"exposure_ms": 44.0},
        {"width_px": 640},
        {"lcos_rate_fps": 400.0},
        {"sensor_preset": "paper"},
        {"object_depth_mm": 501.0},
    ):
        assert proto.with_(**change).digest() != proto.digest(), change


def test_a_bitmap_schedule_is_the_plugins_bitmap_and_its_centroids_are_the_openings(tmp_path):
    cam = _bitmap_design(tmp_path)
    p = sensor_params(cam, "coded")
    assert p["schedule"] == "bitmap" and p["masks"].shape == (8, 1024, 1280)
    proto = preset("prototype")
    # the transmittance-weighted centroids are the discs' centres, to a fraction of an LCoS px
    err = np.abs(cam.pattern_centres_xy_mm() - proto.pattern_centres_xy_mm()[::2]).max()
    assert err < 0.1 * proto.lcos_pitch_mm
    assert cam.schedule_kind == "bitmap" and cam.designed


def test_the_lcos_rate_limits_the_pattern_count():
    fast = preset("prototype").with_(n_patterns=32, exposure_ms=30.0)
    with pytest.raises(ParameterError, match="lcos_rate_fps = 365.*at most 10"):
        fast.check_lcos_rate()
    fast.with_(lcos_rate_fps=1067.0).check_lcos_rate()  # 32 / 30 ms = 1066.7 per s
    preset("prototype").check_lcos_rate()  # 16 in 45 ms at 365 fps


@pytest.mark.parametrize(
    "text, words",
    [
        ("[lens]\nfocus_distance_mm = 700\n[schedule]\nkind = 'parabolic'\n", "exactly one of"),
        (
            "[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 1\nr_px = 2\n"
            "[schedule]\nkind = 'parabolic'\n",
            "exactly one of",
        ),
        ("[opening]\nR_mm = 1\n[schedule]\nkind = 'parabolic'\n", "focus_distance_mm is required"),
        ("[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 1\n", "kind must be one of"),
        (
            "[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 1\n[schedule]\nkind = 'spiral'\n",
            "kind must be one of",
        ),
        (
            "[lens]\nfocus_distance_mm = 700\nzoom = 2\n[opening]\nR_mm = 1\n"
            "[schedule]\nkind = 'parabolic'\n",
            r"unknown keys in \[lens\]",
        ),
        (
            "[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 9\n"
            "[schedule]\nkind = 'parabolic'\n",
            "R_mm must be in",
        ),
        (
            "[lens]\nfocus_distance_mm = 700\n[exposure]\nn_patterns = 32\n[opening]\nR_mm = 1\n"
            "[schedule]\nkind = 'parabolic'\n",
            "lcos_rate_fps",
        ),
        (
            "[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 1\n[schedule]\n"
            "kind = 'centres'\ncentres_mm = [[0, 0]]\n",
            "16 pairs",
        ),
        (
            "[lens]\nfocus_distance_mm = 700\n[opening]\nR_mm = 1\n[schedule]\n"
            "kind = 'bitmap'\nmasks = 'missing.npy'\n",
            "no such file",
        ),
        ("[lens\n", "not valid TOML"),
        ("format = 2\n", "format must be 1"),
        ("[sensor]\nwidth_px = 12.5\n", "width_px must be a positive integer"),
        ("[sensor]\npreset = 3\n", "preset must name"),
    ],
)
def test_a_bad_design_file_is_refused_naming_the_key(tmp_path, text, words):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ParameterError, match=words):
        read_design(p)


def test_a_design_file_that_is_not_utf8_or_has_a_bom(tmp_path):
    p = tmp_path / "latin.toml"
    p.write_bytes("name = 'caf\xe9'\n".encode("latin-1"))
    with pytest.raises(ParameterError, match="UTF-8"):
        read_design(p)
    good = _minimal(tmp_path, "R_mm = 1.5")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + good.read_bytes())
    assert read_design(bom).R_mm == 1.5


def test_masks_outside_the_lens_are_refused(tmp_path):
    masks = disc_masks([[6.0, 0.0]], 2.0)  # reaches 8 mm, past R_max = 6.97 mm
    np.save(tmp_path / "m.npy", masks)
    (tmp_path / "d.toml").write_text(
        "[lens]\nfocus_distance_mm = 700\n[exposure]\nn_patterns = 1\n"
        "[schedule]\nkind = 'bitmap'\nmasks = 'm.npy'\n"
    )
    with pytest.raises(ParameterError, match="outside the lens"):
        read_design(tmp_path / "d.toml")


def test_a_folder_of_lcos_images_is_a_bitmap_schedule(tmp_path):
    from PIL import Image

    cam = _bitmap_design(tmp_path)
    folder = tmp_path / "lcos"
    folder.mkdir()
    for k, m in enumerate(cam.pattern_masks.array):
        Image.fromarray((m * 255).astype(np.uint8)).save(folder / f"pattern_{k:02d}.png")
    (tmp_path / "d.toml").write_text(
        f"[lens]\nfocus_distance_mm = {cam.focus_distance_mm!r}\n[exposure]\nn_patterns = 8\n"
        "[schedule]\nkind = 'bitmap'\nmasks = 'lcos'\n"
    )
    back = read_design(tmp_path / "d.toml")
    assert back.pattern_masks == cam.pattern_masks
    assert back.R_mm == pytest.approx(cam.R_mm)


def test_resolve_design_reads_presets_files_and_records(tmp_path):
    proto = preset("prototype")
    assert resolve_design("prototype") == proto
    path = tmp_path / "d.toml"
    path.write_text(design_toml(proto))
    assert resolve_design(path).digest() == proto.digest()
    assert resolve_design(path, object_depth_mm=600.0).object_depth_mm == 600.0
    (tmp_path / "capture.json").write_text(
        json.dumps({"mode": "normal", "camera": {}, "design": proto.inputs()})
    )
    assert resolve_design(tmp_path / "capture.exr") == proto  # the coded design, not the camera
    with pytest.raises(ParameterError, match="unknown preset"):
        resolve_design("no-such-camera")
    (tmp_path / "x.json").write_text("{}")
    with pytest.raises(ParameterError, match="holds no camera design"):
        resolve_design(tmp_path / "x.json")


def test_square_masks_open_squares_centred_where_the_design_frame_says():
    from pacam_render.model.masks import square_masks

    centres = [[2.0, 0.0], [-1.0, 0.5]]  # x right, y down, mm
    stack = MaskStack(square_masks(centres, 0.5))
    assert np.abs(stack.centroids_xy_mm() - centres).max() < 0.5 * stack.pitch_mm
    side = 2 * 0.5 / stack.pitch_mm  # LCoS px
    assert stack.open_areas_mm2() == pytest.approx(1.0, rel=2 / side)


def test_a_bitmap_design_made_from_a_disc_design_reads_back_with_no_warning(tmp_path):
    """A bitmap design that kept its disc design's R (as ``bitmap_design`` made it) read back
    as "edited after pacam design wrote it": the file's R is the masks' equivalent radius, and
    the header's digest was the unwritten R's. Now the header is the read camera's digest, a
    hand edit is still noted."""
    import re
    import warnings

    from pacam_render.limits import PacamWarning

    disc = preset("prototype")
    stack = _bitmap_design(tmp_path).pattern_masks
    cam = disc.with_(pattern_masks=stack, n_patterns=stack.n_patterns, pattern_centres_mm=None)
    assert cam.R_mm != stack.equivalent_radius_mm()  # the disc's R, kept
    path = tmp_path / "kept_r.toml"
    write_design(path, cam)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)
        back = read_design(path)
    header = re.search(r"^# digest ([0-9a-f]{16});", path.read_text(), re.MULTILINE).group(1)
    assert header == back.digest()
    assert back.R_mm == stack.equivalent_radius_mm()
    assert back.pattern_masks.digest == stack.digest
    path.write_text(path.read_text().replace("exposure_ms = 45.0", "exposure_ms = 40.0"))
    with pytest.warns(PacamWarning, match="was edited after pacam design wrote it"):
        read_design(path)
