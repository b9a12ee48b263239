"""Issue 47: files from outside refused cleanly, before they load (each test fails on the main
before it): masks that are not images, .npy stacks that are not numbers, colour mask PNGs read
as luminance, records nested too deep, and an LCoS switching time longer than a pattern."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.model.masks import load_masks


def test_a_mask_that_is_not_an_image_is_refused_naming_it(tmp_path):
    text = tmp_path / "passwd.png"
    text.write_text("root:x:0:0:root:/root:/bin/bash\n")
    with pytest.raises(ParameterError, match="not an image Mitsuba can read"):
        load_masks(str(text))
    good = tmp_path / "good.npy"
    np.save(good, np.ones((4, 4)))
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)  # a PNG's signature, then nothing
    with pytest.raises(ParameterError, match="broken.png"):
        load_masks(f"{good},{broken}")


@pytest.mark.parametrize("kind", ["strings", "objects", "record", "complex", "truncated"])
def test_a_npy_mask_stack_of_anything_but_numbers_is_refused(tmp_path, kind):
    path = tmp_path / f"{kind}.npy"
    if kind == "strings":
        np.save(path, np.array([["a", "b"], ["c", "d"]]))
    elif kind == "objects":
        np.save(path, np.array([[{}, None]], dtype=object), allow_pickle=True)
    elif kind == "record":
        np.save(path, np.zeros((2, 2), dtype=[("a", "f4"), ("b", "i4")]))
    elif kind == "complex":
        np.save(path, np.ones((2, 2), complex))
    else:
        np.save(path, np.ones((64, 64)))
        path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(ParameterError, match="mask_file"):
        load_masks(str(path))


def test_a_colour_mask_png_is_read_as_luminance(tmp_path):
    import mitsuba as mi

    from pacam_render.render.backend import select_variant

    select_variant()
    rgb = np.zeros((8, 8, 3), np.uint8)
    rgb[:, 4:] = 255
    path = tmp_path / "rgb.png"
    mi.Bitmap(rgb).write(str(path))
    m = load_masks(str(path))
    assert m.shape == (1, 8, 8) and m.min() == 0.0 and m.max() == pytest.approx(1.0)


def test_a_capture_record_nested_too_deep_is_one_line(tmp_path, capsys):
    from pacam_render.exposure.direct import render_capture, write_capture
    from pacam_render.exposure.spec import CaptureSpec

    folder = tmp_path / "cap"
    spec = CaptureSpec.geometric(scene="train", width=32, height=24, mode="reference", spp=4)
    write_capture(render_capture(spec, progress=False, truth=False), folder)
    (folder / "capture.json").write_text("[" * 1_000_000 + "]" * 1_000_000)
    assert main(["deconvolve", str(folder / "capture.exr"), "--psf", "analytic", "--out",
                 str(tmp_path / "d")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "nested too deep" in err and "Traceback" not in err


def test_a_switching_time_longer_than_a_pattern_is_refused_before_mitsuba(capsys, tmp_path):
    args = ["render", "train", "--width", "64", "--height", "48", "--spp", "4", "--diffraction",
            "off", "--lcos-switching", "10", "--quiet", "--out", str(tmp_path / "sw")]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--lcos-switching (10 ms) must be at most a pattern's time: 2.8125 ms" in err
    assert "parser.cpp" not in err and "Traceback" not in err


def test_a_forced_kernel_without_render_takes_the_old_rendered_kernel_away(tmp_path, capsys):
    """Issue 47 item 4: a stale psf_rendered.exr stayed beside a new psf.json that vouched
    for it, and deconvolve took it without a note."""
    out = tmp_path / "g"
    base = ["psf", "--mode", "normal", "--depth", "500", "--quiet", "--out", str(out)]
    assert main([*base, "--velocity", "0.2", "--render", "--spp", "16"]) == 0
    assert (out / "psf_rendered.exr").is_file()
    assert main([*base, "--velocity", "0", "--force"]) == 0
    assert not (out / "psf_rendered.exr").exists() and not (out / "psf_rendered.png").exists()
    assert (out / "psf_analytic.exr").is_file()


def _capture_folder(tmp_path):
    from pacam_render.exposure.direct import render_capture, write_capture
    from pacam_render.exposure.spec import CaptureSpec

    folder = tmp_path / "cap"
    spec = CaptureSpec.geometric(scene="train", width=32, height=24, mode="coded", spp=4)
    write_capture(render_capture(spec, progress=False, truth=False), folder)
    return folder


@pytest.mark.parametrize("value", ['"abc"', "NaN", "Infinity", "null", "[64]"])
def test_an_edited_camera_in_a_capture_record_is_one_line(tmp_path, capsys, value):
    import json
    import re

    folder = _capture_folder(tmp_path)
    path = folder / "capture.json"
    text = path.read_text()
    d = json.loads(text)
    w = d["camera"]["width_px"]
    path.write_text(re.sub(rf'"width_px": {w}', f'"width_px": {value}', text, count=1))
    assert main(["deconvolve", str(folder / "capture.exr"), "--psf", "analytic", "--out",
                 str(tmp_path / "d")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "capture.json: camera" in err and "Traceback" not in err


def test_a_pattern_count_is_bounded_and_a_mask_bomb_refused_before_it_inflates():
    import base64
    import zlib

    from pacam_render.model.camera import prototype
    from pacam_render.model.masks import MaskStack

    with pytest.raises(ParameterError, match="at most 4096"):
        prototype().with_(n_patterns=10**6, lcos_rate_fps=1e12)
    blob = base64.b64encode(zlib.compress(b"\\0" * 2**20)).decode()
    bomb = {"shape": [16, 4096, 8192], "dtype": "uint8", "zlib_base64": blob,
            "pitch_mm": 0.01362, "digest": "x"}  # fmt: skip
    with pytest.raises(ParameterError, match="MiB a stack may take"):
        MaskStack.from_json(bomb)
    small = {**bomb, "shape": [2, 4, 4], "digest": None}
    with pytest.raises(ParameterError, match="digest is missing"):
        MaskStack.from_json(small)


def test_optimize_keeps_a_design_files_pattern_count(tmp_path):
    """Issue 47 medium 8: `optimize --design fast.toml` (32 patterns in 30 ms) wrote a
    16-pattern design.toml with no note."""
    from pacam_render.model.design_file import read_design

    assert main(["design", "--max-velocity", "2", "--n-patterns", "32", "--exposure", "30",
                 "--lcos-rate", "1100", "--write", str(tmp_path / "fast.toml")]) == 0  # fmt: skip
    out = tmp_path / "opt"
    args = [
        "optimize",
        "--max-velocity",
        "2",
        "--design",
        str(tmp_path / "fast.toml"),
        "--quick",
        "--starts",
        "1",
        "--iterations",
        "2",
        "--quiet",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    assert read_design(out / "design.toml").n_patterns == 32


def test_a_scene_that_names_a_device_or_a_huge_mesh_is_refused_before_it_loads(tmp_path, capsys):
    """High 10: a ply at /dev/zero read 99 s up to 17 GB; a sparse 5 GiB file stands for a
    mesh past the bound (nothing of it is read)."""
    zero = tmp_path / "zero.xml"
    zero.write_text('<scene version="3.0.0"><shape type="ply"><string name="filename" '
                    'value="/dev/zero"/></shape></scene>')  # fmt: skip
    args = ["render", str(zero), "--width", "32", "--height", "24", "--spp", "4", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert "'/dev/zero' (/dev/zero), which is not a regular file" in capsys.readouterr().err
    huge = tmp_path / "huge.ply"
    with open(huge, "wb") as f:
        f.truncate(5 * 2**30)
    big = tmp_path / "big.xml"
    big.write_text('<scene version="3.0.0"><shape type="ply"><string name="filename" '
                   'value="huge.ply"/></shape></scene>')  # fmt: skip
    args[1] = str(big)
    assert main([*args, "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "'huge.ply'" in err and "5.0 GiB, over the 4 GiB" in err


def test_a_full_disk_ends_in_one_line_and_the_capture_is_rescued(tmp_path, capsys, monkeypatch):
    """High 9: OpenEXR reports a full disk as a RuntimeError; the capture's write becomes one
    line naming the path, and the capture is written to a temporary folder instead."""
    import sys

    import OpenEXR

    out = tmp_path / "cap"

    class FullDisk:  # OpenEXR.File, whose writes into `out` fail as a full disk does
        def __init__(self, *a):
            self.file = OpenEXR.File(*a)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return self.file.__exit__(*exc)

        def write(self, path):
            if str(out) in str(path):
                raise RuntimeError(
                    f'Failed to write pixel data to "{path}". No space left on device.'
                )
            self.file.write(path)

    fake = type(sys)("OpenEXR")
    fake.__dict__.update(OpenEXR.__dict__)
    fake.File = FullDisk
    monkeypatch.setitem(sys.modules, "OpenEXR", fake)
    args = ["render", "train", "--width", "48", "--height", "36", "--spp", "4", "--diffraction",
            "off", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    line = err[-1]
    assert line.startswith("pacam render: error: writing the capture to") and "Traceback" not in err
    assert "no space left on device" in line and str(out / "capture.exr") in line
    rescue = line.split("the capture was written to ")[1].split(":")[0]
    from pathlib import Path

    assert (Path(rescue) / "capture.exr").is_file()


def test_a_scene_that_includes_a_non_xml_file_is_refused_and_reading_outside_is_said(
    tmp_path, capsys
):
    """Medium 10: `<include filename="/etc/passwd">` was read (its line count in the error);
    a mesh named by ../ was read with no word."""
    inc = tmp_path / "inc.xml"
    inc.write_text('<scene version="3.0.0"><include filename="/etc/passwd"/></scene>')
    args = ["render", str(inc), "--width", "32", "--height", "24", "--spp", "4", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert "includes '/etc/passwd', which is not a .xml scene file" in capsys.readouterr().err
    (tmp_path / "tri.obj").write_text("v -50 -50 0\nv 50 -50 0\nv 0 50 0\nf 1 2 3\n")
    (tmp_path / "s").mkdir()
    scene = tmp_path / "s" / "s.xml"
    scene.write_text('<scene version="3.0.0"><shape type="obj"><string name="filename" '
                     'value="../tri.obj"/><transform name="to_world"><translate z="500"/>'
                     '</transform></shape></scene>')  # fmt: skip
    args[1] = str(scene)
    assert main([*args, "--diffraction", "off", "--out", str(tmp_path / "b")]) == 0
    assert "reads '../tri.obj', outside its folder" in capsys.readouterr().err


def test_an_edited_camera_radius_in_a_capture_record_is_refused_by_its_digest(tmp_path, capsys):
    """Medium 3: camera.R_mm edited from 1.98 to 1.5 was taken by psf --like and deconvolve;
    the recorded optics.design_digest now refuses it."""
    import json

    cap = tmp_path / "cap"
    assert main(["render", "train", "--width", "32", "--height", "24", "--spp", "4",
                 "--diffraction", "off", "--quiet", "--out", str(cap)]) == 0  # fmt: skip
    meta = json.loads((cap / "capture.json").read_text())
    meta["camera"]["R_mm"] = 1.5
    (cap / "capture.json").write_text(json.dumps(meta))
    capsys.readouterr()
    like = ["psf", "--like", str(cap / "capture.exr"), "--velocity", "0"]
    assert main([*like, "--out", str(tmp_path / "p")]) == 2
    assert "its 'camera' was edited" in capsys.readouterr().err
    assert main(["deconvolve", str(cap / "capture.exr"), "--out", str(tmp_path / "d")]) == 2
    assert "optics.design_digest" in capsys.readouterr().err


def test_a_curve_whose_axis_value_is_wrong_is_refused_before_the_render(tmp_path, capsys):
    """Mediums 4-6: a curve starting at 1e-300 ran the whole render, then exited 2 with
    nothing written; one rising to 5x went by with no word; its messages named the flag for
    the file's own column."""
    bad = tmp_path / "bad.csv"
    bad.write_text("height_px,relative_illumination\n0,1e-300\n400,0.9\n800,0.8\n")
    args = ["render", "train", "--width", "48", "--height", "36", "--spp", "4", "--quiet",
            "--diffraction", "off", "--relative-illumination"]  # fmt: skip
    assert main([*args, str(bad), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "relative_illumination reaches 9e+299x its value on the axis" in err
    assert not (tmp_path / "a" / ".partial").exists()
    odd = tmp_path / "odd.csv"
    odd.write_text("height_px,relative_illumination\n0,1\n400,5\n800,0.8\n")
    assert main([*args, str(odd), "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert err.count("rises to 5x its value on the axis") == 1


def test_a_slit_too_narrow_to_measure_its_diffraction_still_renders(tmp_path, capsys):
    """Found while timing bitmaps (issue 46, item 4): with diffraction off, a schedule of
    3-pixel slits failed the whole render, because the budget's measure of what diffraction
    would do needs a kernel of ~9600 px. The budget now says it is not measured."""
    import json

    m = np.zeros((16, 64, 64), np.float32)
    for k in range(16):
        m[k, :, 4 + 3 * k : 7 + 3 * k] = 1.0
    np.save(tmp_path / "slits.npy", m)
    design = tmp_path / "slit.toml"
    assert main(["design", "--masks", str(tmp_path / "slits.npy"), "--write", str(design)]) == 0
    out = tmp_path / "c"
    args = ["render", "train", "--design", str(design), "--crop", "400,500,48,32", "--spp", "8",
            "--diffraction", "off", "--no-truth", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    entry = json.loads((out / "capture.json").read_text())["optics_error"]["effects"]
    assert entry["diffraction"]["size_rms"] is None
    assert entry["diffraction"]["estimate"].startswith("not measured: a diffraction kernel")


def test_a_bad_mask_source_is_named_as_the_user_gave_it(tmp_path, capsys):
    """A design file's masks are its `[schedule] masks`, the command line's `--masks`; both
    were called `mask_file` (the plugin's parameter)."""
    text = tmp_path / "notes.png"
    text.write_text("not an image\n")
    d = tmp_path / "d.toml"
    d.write_text('[lens]\nfocus_distance_mm = 751.6\n[schedule]\nkind = "bitmap"\n'
                 f'masks = "{text.name}"\n')  # fmt: skip
    assert main(["design", "--design", str(d)]) == 2
    assert "[schedule] masks: " in capsys.readouterr().err
    assert main(["design", "--masks", str(text)]) == 2
    assert "error: --masks: " in capsys.readouterr().err
