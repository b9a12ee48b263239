"""Issue 56's lows and two mediums: refusals and notes that name what to change.

Item 1: a refocus beyond a store's margin advises ``--margin-px`` on the command line, and a store
rendered with the margin it names serves that refocus (the advice is checked by following it).

Item 3: ``pacam render soccer --from STORE`` of a train store said the scene's digest differs;
it names the store's scene and the command that synthesises from it.

Item 2: an all-black mask stack was refused as "R_mm must be > 0"; it is refused as black,
naming the masks (reference: a stack with one closed frame is taken, its R the mean open area's).

Item 4: ``pacam design`` with other ``--n-patterns``/``--exposure`` wrote the name "prototype";
the name says what changed (reference: the prototype's own values keep its name and digest).

Item 5 (medium): a far-off design failed with no warning at any step. The solver (and so
``pacam design``) notes a defocus radius over 4x the prototype's; ``restore_capture`` (and so
``pacam deconvolve``) notes an estimate that scores below its own blurred input.
"""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
from PIL import Image

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture, write_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.io.exr import read_exr
from pacam_render.io.toml_file import read_toml
from pacam_render.lightfield import Store, synthesize
from pacam_render.limits import PacamWarning
from pacam_render.model.camera import CameraDesign, preset
from pacam_render.model.design import FAR_R_FACTOR, solve
from pacam_render.model.design_file import resolve_design
from pacam_render.model.masks import MaskStack, disc_masks
from pacam_render.restore import restoration
from pacam_render.restore.metrics import aligned_psnr, shift_search_px
from pacam_render.restore.restoration import restore_capture

CROP = "456,410,16,12"


def _store(path, *extra) -> None:
    argv = ["lightfield", "train", "--crop", CROP, "--spp", "4", "--passes", "2", "--quiet"]
    assert main([*argv, *extra, "--out", str(path)]) == 0


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("lf") / "store"
    _store(path)
    return path


@pytest.mark.render
def test_a_refocus_beyond_the_margin_advises_the_flag_that_serves_it(store, tmp_path, capsys):
    refocus = ["render", "train", "--mode", "normal", "--depth", "300", "--quiet"]
    capsys.readouterr()
    assert main([*refocus, "--from", str(store), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    need = re.search(r"--margin-px >= (\d+)", err)
    assert need, err
    assert not (tmp_path / "a" / "capture.exr").exists()
    wide = tmp_path / "wide"
    _store(wide, "--margin-px", need.group(1))  # the advice, followed
    assert main([*refocus, "--from", str(wide), "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "capture.exr").exists()


@pytest.mark.render
def test_another_scene_from_a_store_names_the_stores_scene(store, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "cap"
    assert main(["render", "soccer", "--from", str(store), "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "scene 'train'" in err and f"pacam render train --from {store}" in err, err
    assert not out.exists()
    lf = Store.open(store)
    spec = CaptureSpec.geometric(scene="soccer", width=1280, height=960, crop=(456, 410, 16, 12))
    with pytest.raises(ParameterError, match="is of scene 'train', not `scene` 'soccer'"):
        synthesize(lf, spec, progress=False)


def _black_png(path) -> None:
    Image.fromarray(np.zeros((64, 64), np.uint8)).save(path)


def test_all_black_masks_are_refused_as_black_not_as_an_opening_of_zero(tmp_path, capsys):
    """Item 2: an all-black stack was refused as 'R_mm must be > 0'; it is refused naming the
    masks, in the library, a design file and ``pacam design --masks``."""
    black = MaskStack(np.zeros((2, 64, 64), np.float32))
    proto = preset("prototype")
    for radius, name in ((black.equivalent_radius_mm, "masks"), (lambda: 0.0, "pattern_masks")):
        with pytest.raises(ParameterError) as err:  # R from the masks, or the R they give: 0
            proto.with_(pattern_masks=black, n_patterns=2, pattern_centres_mm=None, R_mm=radius())
        assert str(err.value).startswith(f"{name}: the masks are all black: no light passes")
        assert "R_mm" not in str(err.value)
    one_closed = np.concatenate([disc_masks([0.0], 0.3, shape=(64, 64)), np.zeros((1, 64, 64))])
    stack = MaskStack(one_closed.astype(np.float32))  # a closed frame is a shutter: taken
    d = proto.with_(pattern_masks=stack, n_patterns=2, pattern_centres_mm=None,
                    R_mm=stack.equivalent_radius_mm())  # fmt: skip
    assert d.R_mm == pytest.approx(np.sqrt(one_closed.sum() / 2 / np.pi) * stack.pitch_mm)
    _black_png(tmp_path / "black.png")
    (tmp_path / "d.toml").write_text(
        '[lens]\nfocus_distance_mm = 751.6\n[schedule]\nkind = "bitmap"\nmasks = "black.png"\n'
    )
    with pytest.raises(
        ParameterError, match=r"^\[schedule\] masks \(black.png\): the masks are all"
    ):
        resolve_design(str(tmp_path / "d.toml"))
    capsys.readouterr()
    assert main(["design", "--masks", str(tmp_path / "black.png")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert f"--masks ({tmp_path / 'black.png'}): the masks are all black" in err, err


def test_a_design_changed_by_flags_is_named_for_its_changes(tmp_path, capsys):
    """Item 4: ``pacam design --n-patterns 32 --exposure 20`` wrote a design named
    "prototype"; the written name says what changed, and the file is that design."""

    def written(*flags) -> CameraDesign:
        path = tmp_path / "d.toml"
        assert main(["design", *flags, "--write", str(path), "--force"]) == 0
        name = read_toml(path)["name"]
        d = resolve_design(str(path))
        assert d.name == name
        return d

    d = written("--n-patterns", "32", "--exposure", "20", "--lcos-rate", "2000")
    assert (d.n_patterns, d.exposure_ms, d.lcos_rate_fps) == (32, 20.0, 2000.0)
    assert d.name == "prototype, 32 patterns in 20 ms, LCoS at 2000 patterns/s"
    assert written("--exposure", "60").name == "prototype, 16 patterns in 60 ms"
    proto = preset("prototype")
    same = written("--n-patterns", str(proto.n_patterns))  # the prototype's own: unchanged
    assert same.name == "prototype" and same.digest() == proto.digest()


def test_a_far_design_is_noted_by_the_solver_and_pacam_design(tmp_path, capsys):
    """Item 5a: ``--max-velocity 1.2 --f-number 4 --depth 450`` solved r = 15.75 px (8x the
    prototype's 2 px) silently. Reference: Eq. 18 solved for r at that F-number by hand."""
    proto = preset("prototype")
    R = proto.R_max_mm * proto.F_min / 4.0
    r = 1.2 * (proto.exposure_ms / 2) / (4.0 * (proto.R_max_mm / R - 1.0))
    with pytest.warns(PacamWarning, match=r"defocus radius r = 15.7 px is 7.9x") as rec:
        d = solve(1.2, f_number=4.0, object_depth_mm=450.0)
    assert d.r_px == pytest.approx(r) and r / 2.0 > FAR_R_FACTOR
    assert len(rec) == 1
    for kw in ({}, {"r_px": FAR_R_FACTOR * 2.0}):  # the paper's speed; at the threshold
        with warnings.catch_warnings():
            warnings.simplefilter("error", PacamWarning)
            solve(1.2, **kw)
    capsys.readouterr()
    argv = ["design", "--max-velocity", "1.2", "--f-number", "4", "--depth", "450"]
    assert main([*argv, "--write", str(tmp_path / "f4.toml")]) == 0
    notes = [x for x in capsys.readouterr().err.splitlines() if "note:" in x]
    assert len(notes) == 1 and "7.9x the prototype's 2 px" in notes[0] and "--r-px" in notes[0]
    assert main(["design", "--design", str(tmp_path / "f4.toml"), "--json"]) == 0
    assert "7.9x the prototype's" in capsys.readouterr().err  # read back, noted again


@pytest.fixture(scope="module")
def small_capture():
    spec = CaptureSpec(scene="train", mode="coded", width=64, height=48, spp=16, seed=4,
                       diffraction="off")  # fmt: skip
    return render_capture(spec, progress=False)


@pytest.mark.render
def test_a_restoration_worse_than_its_input_is_noted(small_capture, monkeypatch, tmp_path, capsys):
    """Item 5b: ``deconvolve`` returned -2.12 dB against the blurred input's 16.03 dB with no
    note. A deconvolver returning zeros is noted with both PSNRs; the input's is recomputed
    here from what the deconvolver was given (divided by the light factor, best shift)."""
    cap = small_capture
    given = {}

    def zeros(data, kernel, method, **kw):
        given["data"] = np.array(data)
        return np.zeros_like(data)

    monkeypatch.setattr(restoration, "deconvolve", zeros)
    with pytest.warns(PacamWarning, match="below the blurred input") as rec:
        res = restore_capture(cap, method="wiener")
    sharp = cap.extra_layers["sharp"]
    blurred = aligned_psnr(given["data"] / cap.record.light_factor, sharp, (0, 1, 0, 1),
                           shift_search_px(64))  # fmt: skip
    assert blurred > res.score["psnr_db"]
    text = str(rec[-1].message)
    assert f"{res.score['psnr_db']:.2f} dB" in text and f"{blurred:.2f} dB" in text, text
    write_capture(cap, tmp_path / "cap")
    capsys.readouterr()
    argv = ["deconvolve", str(tmp_path / "cap"), "--method", "wiener", "--out", str(tmp_path / "d")]
    assert main(argv) == 0
    notes = [x for x in capsys.readouterr().err.splitlines() if "below the blurred input" in x]
    assert len(notes) == 1 and "note:" in notes[0] and f"{blurred:.2f} dB" in notes[0], notes

    def truth(data, kernel, method, **kw):  # the sharp image itself: better than its input
        return sharp * cap.record.light_factor

    monkeypatch.setattr(restoration, "deconvolve", truth)
    monkeypatch.setattr(restoration, "to_pinhole", lambda image, origin, offset: image)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)
        assert restore_capture(cap, method="wiener").score["psnr_db"] > blurred


def test_the_diffraction_numbers_say_where_each_was_measured():
    """Low: three diffraction numbers on one screen (the preview's effect, the budget's, the
    predicted sigma). The budget's line says it is measured on the capture where auto
    decided on a preview, and an exact-rays residual says it is a scale, not a bound (it
    was called 'what its approximation leaves out' and exceeded the whole effect)."""
    from pacam_render.capture.optics_error import summary_line
    from pacam_render.exposure.optics.budget import _EXACT_RAYS, _HOW_SIZED

    left = {"included": False, "size_rms": 2e-4, "ratio_to_sensor": 0.5}
    block = {"largest_left_out": "diffraction", "effects": {"diffraction": left},
             "diffraction": {"setting": "auto"}, "reference_noise": {"sigma": 4e-4}}  # fmt: skip
    assert "measured on the capture; auto decided on its preview" in summary_line(block)
    block["diffraction"]["setting"] = "off"
    assert "preview" not in summary_line(block)
    scale = {"included": True, "residual": True, "size_rms": 1e-4, "ratio_to_sensor": 0.2,
             "estimate": _HOW_SIZED[_EXACT_RAYS]}  # fmt: skip
    block["effects"]["diffraction"] = scale
    line = summary_line(block)
    assert "scale of what rays cannot do at occluding edges, not a bound" in line
    assert "leaves out" not in line


@pytest.mark.render
def test_lightfield_prints_an_estimate_and_remembers_what_it_traced(tmp_path, capsys, monkeypatch):
    """Low: ``lightfield`` printed no time estimate. It says one before tracing, and its
    history row counts the samples the manifest's steps hold over the film with its margin
    (arithmetic on store.json, not the estimate's code)."""
    history = tmp_path / "times.jsonl"
    monkeypatch.setenv("PACAM_RENDER_TIMES", str(history))
    argv = ["lightfield", "train", "--crop", CROP, "--spp", "4", "--passes", "2"]
    assert main([*argv, "--out", str(tmp_path / "s")]) == 0
    assert re.search(r"estimate: about [0-9.]+ (s|min)", capsys.readouterr().err)
    manifest = json.loads((tmp_path / "s" / "store.json").read_text())
    m, (_, _, w, h) = manifest["camera"]["margin_px"], manifest["camera"]["window"]
    samples = sum(s[2] for p in manifest["steps"] for s in p) * (w + 2 * m) * (h + 2 * m)
    (row,) = [json.loads(x) for x in history.read_text().splitlines()]
    assert row["key"].startswith("lightfield ")
    assert row["msamples"] == pytest.approx(samples / 1e6)
    assert row["renders"] == sum(len(p) for p in manifest["steps"])


@pytest.mark.render
def test_a_grey_store_serves_grey_captures_without_grey(tmp_path, capsys):
    """Low: ``render --from`` a grey store without ``--grey`` was refused; the store's
    channels are taken, as its window and spp are. The capture is one channel, and equals
    the one asked with ``--grey`` (same store, same seed)."""
    _store(tmp_path / "grey", "--grey")
    base = ["render", "train", "--from", str(tmp_path / "grey"), "--mode", "coded", "--quiet"]
    assert main([*base, "--out", str(tmp_path / "a")]) == 0
    assert main([*base, "--grey", "--out", str(tmp_path / "b")]) == 0
    a, b = read_exr(tmp_path / "a" / "capture.exr"), read_exr(tmp_path / "b" / "capture.exr")
    assert a["capture"].ndim == 2 and np.array_equal(a["capture"], b["capture"])
