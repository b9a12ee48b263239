"""Your own camera through every command (issue 35): ``pacam design --write``, ``--design`` on
render, psf and study, ``psf --like`` that reproduces the capture's camera exactly, and a PSF
file made for another camera refused by ``deconvolve``.

References: each capture's own record (its r, a_i and pattern count, Eqs. 12 and 18, written by
the renderer's side), and the prototype's figures, which a kernel made for another design must
not carry. On main before this issue, ``psf --like`` wrote the prototype's kernel (r 2 px,
a_i -0.0398) for a ``--cover 1.4`` capture (r 3.13 px, a_i -0.0622), and ``deconvolve`` took it.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.model.camera import preset
from pacam_render.model.design_file import read_design, write_design
from pacam_render.model.masks import MaskStack, disc_masks

pytestmark = pytest.mark.render

CROP = "540,430,96,64"  # a window of the full sensor around the near train
FIGURES = ("r_px", "a_i_px_per_ms2", "n_patterns", "exposure_ms", "design_digest")


def _render(out, *extra) -> dict:
    # the design's road, not the optics (tests/exposure/test_capture_diffraction_render.py):
    # auto's preview would double each render
    args = ["render", "train", "--crop", CROP, "--spp", "4", "--quiet", "--out", str(out),
            "--diffraction", "off"]  # fmt: skip
    assert main([*args, *extra]) == 0
    return json.loads((out / "capture.json").read_text())


def _schedule_json(path) -> None:
    """An 8-pattern designed schedule: every second opening of the prototype's parabola,
    0.7x as wide (a_i 0.7x the prototype's, fitted)."""
    proto = preset("prototype")
    doc = {
        "n_patterns": 8,
        "centres_mm": (0.7 * proto.pattern_centres_xy_mm()[::2]).tolist(),  # its own a_i
        "radius_mm": proto.R_mm,
        "focus_distance_mm": proto.focus_distance_mm,
    }
    path.write_text(json.dumps(doc))


def _bitmap_design(path) -> None:
    """A design file of LCoS bitmaps: 8 discs along the parabola, written by the library."""
    proto = preset("prototype")
    stack = MaskStack(disc_masks(-proto.pattern_centres_xy_mm()[::2], proto.R_mm))
    cam = proto.with_(
        pattern_masks=stack, n_patterns=8, R_mm=stack.equivalent_radius_mm(), name="bitmaps"
    )
    write_design(path, cam)


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    root = tmp_path_factory.mktemp("designs")
    _schedule_json(root / "schedule.json")
    _bitmap_design(root / "bitmaps.toml")
    return root, {
        "cover": _render(root / "cover", "--cover", "1.4"),
        "schedule": _render(root / "sched", "--schedule", str(root / "schedule.json")),
        "bitmap": _render(root / "bitmap", "--design", str(root / "bitmaps.toml")),
    }


@pytest.mark.parametrize("name", ["cover", "schedule", "bitmap"])
def test_psf_like_writes_the_kernel_of_the_capture_s_own_camera(captures, name):
    root, caps = captures
    folder = {"cover": "cover", "schedule": "sched", "bitmap": "bitmap"}[name]
    out = root / f"psf_{name}"
    assert main(["psf", "--like", str(root / folder / "capture.exr"), "--velocity", "0",
                 "--out", str(out)]) == 0  # fmt: skip
    psf = json.loads((out / "psf.json").read_text())
    optics = caps[name]["optics"]
    for key in FIGURES:
        assert psf[key] == optics[key], key
    proto = preset("prototype")
    assert psf["design_digest"] != proto.digest()
    if name == "cover":  # the figures the issue quotes
        assert psf["r_px"] == pytest.approx(3.126, abs=1e-3)
        assert psf["a_i_px_per_ms2"] == pytest.approx(-0.0622, abs=1e-4)
    else:
        assert psf["n_patterns"] == 8
    if name == "schedule":  # fitted to its own openings: 0.7x the prototype's a_i
        assert psf["a_i_px_per_ms2"] == pytest.approx(0.7 * proto.a_i_px_per_ms2, rel=1e-6)
    assert psf["schedule_kind"] == {"cover": "parabolic", "schedule": "centres",
                                    "bitmap": "bitmap"}[name]  # fmt: skip


def test_a_capture_embeds_its_whole_design_bitmaps_included(captures):
    root, caps = captures
    cam = read_design(root / "bitmaps.toml")
    rec = caps["bitmap"]
    assert rec["camera"]["pattern_masks"]["digest"] == cam.pattern_masks.digest
    assert rec["optics"]["design_digest"] == cam.with_(width_px=1280).digest()
    assert rec["sensor_params"]["schedule"] == "bitmap"


def test_deconvolve_refuses_a_kernel_of_another_camera_naming_r_and_a_i(captures, capsys):
    root, _ = captures
    proto_psf = root / "proto_psf"
    assert main(["psf", "--velocity", "0", "--origin", "pinhole", "--out", str(proto_psf)]) == 0
    cap = str(root / "cover" / "capture.exr")
    kernel = str(proto_psf / "psf_analytic.exr")
    capsys.readouterr()
    assert main(["deconvolve", cap, "--psf", kernel, "--out", str(root / "d1")]) == 2
    err = capsys.readouterr().err
    assert "r 2 px (PSF) against 3.126 px (capture)" in err
    assert "a_i -0.0398 px/ms^2 (PSF) against -0.06222 px/ms^2 (capture)" in err
    assert "--allow-psf-mismatch" in err and "Traceback" not in err
    assert not (root / "d1").exists()
    # on purpose (Fig. 9's wrong assumed depth): done, with a note, and recorded
    assert main(["deconvolve", cap, "--psf", kernel, "--allow-psf-mismatch",
                 "--out", str(root / "d2")]) == 0  # fmt: skip
    assert "mismatched PSF" in capsys.readouterr().err
    meta = json.loads((root / "d2" / "deconvolved.json").read_text())
    assert any(m.startswith("r 2 px") for m in meta["psf"]["mismatch"])
    # the capture's own kernel is taken without a word
    like = root / "psf_like_cover"
    assert main(["psf", "--like", cap, "--velocity", "0", "--out", str(like)]) == 0
    assert main(["deconvolve", cap, "--psf", str(like / "psf_analytic.exr"),
                 "--out", str(root / "d3")]) == 0  # fmt: skip
    assert "mismatch" not in json.loads((root / "d3" / "deconvolved.json").read_text())["psf"]


def test_a_kernel_at_another_depth_is_a_mismatch_too(captures, capsys):
    root, _ = captures
    cap = str(root / "sched" / "capture.exr")
    out = root / "psf_far"
    assert main(["psf", "--like", cap, "--depth", "700", "--velocity", "0",
                 "--out", str(out)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["deconvolve", cap, "--psf", str(out / "psf_analytic.exr"),
                 "--out", str(root / "d_far")]) == 2  # fmt: skip
    assert "depth 700 mm (PSF) against 500 mm (capture)" in capsys.readouterr().err


def test_a_32_pattern_design_file_through_design_render_psf_and_deconvolve(tmp_path, capsys):
    design = tmp_path / "fast.toml"
    assert main(["design", "--max-velocity", "2", "--n-patterns", "32", "--exposure", "30",
                 "--lcos-rate", "1200", "--write", str(design)]) == 0  # fmt: skip
    cam = read_design(design)
    assert (cam.n_patterns, cam.exposure_ms) == (32, 30.0)
    assert cam.velocity_range_px_per_ms == pytest.approx(2.0)
    rec = _render(tmp_path / "cap", "--design", str(design))
    assert rec["optics"]["design_digest"] == cam.digest()
    assert rec["optics"]["n_patterns"] == 32
    cap = str(tmp_path / "cap" / "capture.exr")
    assert main(["psf", "--like", cap, "--velocity", "0", "--out", str(tmp_path / "k")]) == 0
    assert main(["deconvolve", cap, "--psf", str(tmp_path / "k" / "psf_analytic.exr"),
                 "--out", str(tmp_path / "d")]) == 0  # fmt: skip
    # the prototype's 365 fps LCoS cannot show it: said before any work
    capsys.readouterr()
    assert main(["design", "--max-velocity", "2", "--n-patterns", "32", "--exposure", "30"]) == 2
    assert "--lcos-rate = 365" in capsys.readouterr().err


def test_psf_takes_cover_and_design_flags_and_like_refuses_them(tmp_path, capsys):
    out = tmp_path / "k"
    assert main(["psf", "--cover", "1.4", "--velocity", "0", "--out", str(out)]) == 0
    psf = json.loads((out / "psf.json").read_text())
    assert psf["r_px"] == pytest.approx(3.126, abs=1e-3)
    np.testing.assert_allclose(psf["velocity_range_px_per_ms"], 1.4, rtol=1e-9)
    capsys.readouterr()
    assert main(["psf", "--like", "x.exr", "--cover", "1", "--velocity", "0",
                 "--out", str(tmp_path / "q")]) == 2  # fmt: skip
    assert "leave out --cover" in capsys.readouterr().err


def test_a_study_design_axis_lists_design_files(tmp_path, capsys):
    """One point per design file; the row and its render record the file's camera."""
    fast = tmp_path / "fast.toml"
    assert main(["design", "--max-velocity", "2", "--n-patterns", "32", "--exposure", "30",
                 "--lcos-rate", "1200", "--write", str(fast)]) == 0  # fmt: skip
    spec = tmp_path / "s.toml"
    spec.write_text(
        '[study]\nname = "designs"\nreport = "crossover"\n'
        "[render]\nwidth = 64\nheight = 48\nspp = 4\nmax_step_px = 4.0\n"
        f'[grid]\nmode = ["coded"]\ndesign = ["prototype", "{fast}"]\nlight_level = [3000.0]\n'
    )
    out = tmp_path / "out"
    assert main(["study", str(spec), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    import csv

    with open(out / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert {r["design"] for r in rows} == {"prototype", str(fast)}
    cam = read_design(fast)
    by = {r["design"]: r for r in rows}
    assert float(by[str(fast)]["a_i_px_per_ms2"]) == pytest.approx(
        cam.with_(width_px=64, height_px=48).a_i_px_per_ms2
    )


def test_psf_rendered_and_its_advice_work_as_written(captures, capsys):
    """``deconvolve --psf rendered`` names the command that makes the file; run as printed
    (into the capture's own folder, beside capture.json), it makes deconvolve work."""
    import shlex

    root, _ = captures
    cap = root / "cover" / "capture.exr"
    capsys.readouterr()
    assert main(["deconvolve", str(cap), "--psf", "rendered", "--out", str(root / "r1")]) == 2
    err = capsys.readouterr().err
    advice = err.split("make it with pacam ", 1)[1].split(" (the capture's", 1)[0]
    args = shlex.split(advice) + ["--spp", "8", "--quiet"]
    assert main(args) == 0
    assert (cap.parent / "capture.json").is_file() and (cap.parent / "psf_rendered.exr").is_file()
    assert main(["deconvolve", str(cap), "--psf", "rendered", "--out", str(root / "r1")]) == 0
    # a second psf into the same folder is refused without --force, the capture kept
    assert main(args) == 2
    assert "pass --force" in capsys.readouterr().err
