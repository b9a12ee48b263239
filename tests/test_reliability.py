"""Issue 12's probes, one test each: resuming that cannot mix captures, locks, determinism,
interrupts, output paths, bounded work, physical limits, saturation, deconvolution traps,
notes for ignored options, and flag names in messages."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.checkpoint import Checkpoint
from pacam_render.exposure.direct import CaptureInterrupted, check_budget, render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.exposure.steps import plan_steps
from pacam_render.io.exr import read_layer, write_exr
from pacam_render.limits import PacamWarning
from pacam_render.model.camera import CameraDesign, prototype
from pacam_render.model.report import design_report
from pacam_render.render.passes import MAX_CHUNK_SAMPLES, MAX_PASS_SPP, split_spp
from pacam_render.restore.deconvolve import METHODS, deconvolve
from tests.patching import patch_everywhere

SCENE_XML = """<scene version='3.0.0'>
    <shape type='rectangle' id='wall'>
        <transform name='to_world'><scale value='400'/><translate z='1500'/></transform>
        <bsdf type='diffuse'><texture type='checkerboard' name='reflectance'>
            <transform name='to_uv'><scale value='8'/></transform></texture></bsdf>
    </shape>
    <shape type='sphere' id='ball'>
        <point name='center' x='0' y='0' z='{z}'/><float name='radius' value='40'/>
    </shape>
    <emitter type='constant'/>
</scene>"""


def _scene_files(folder, velocity: float, z: float = 500.0):
    xml = folder / "m.xml"
    xml.write_text(SCENE_XML.format(z=z))
    motion = {"shapes": {"ball": {"velocity_mm_per_ms": [velocity, 0.0, 0.0]}}}
    (folder / "m.motion.json").write_text(json.dumps(motion))
    return xml


# --- 1. resume keys ------------------------------------------------------------------------------
@pytest.mark.render
def test_resume_starts_afresh_when_the_motion_or_the_scene_changed(tmp_path):
    xml = _scene_files(tmp_path, -0.3)
    spec = CaptureSpec.geometric(scene=str(xml), mode="coded", width=32, height=24, spp=64)
    part = tmp_path / "out" / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=8)
    _scene_files(tmp_path, 3.0)  # the probe: same path, new motion
    # the faster motion also takes the sampler of finer steps (steps.fine_step_sampler): the
    # spec's key may change with it
    with pytest.warns(PacamWarning, match=r"different capture \((spec, )?motion, steps changed\)"):
        resumed = render_capture(spec, partial_dir=part, progress=False)
    assert resumed.meta["resumed_from_step"] == 0
    assert any("starting afresh" in n for n in resumed.record.notes)
    fresh = render_capture(spec, progress=False)
    assert np.array_equal(resumed.image, fresh.image)

    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=3)
    _scene_files(tmp_path, 3.0, z=520.0)  # the XML's contents change, its motion does not
    with pytest.warns(PacamWarning, match=r"\(scene changed\)"):
        assert render_capture(spec, partial_dir=part, progress=False).meta["resumed_from_step"] == 0


def test_checkpoint_survives_a_stale_fixed_temporary_name(tmp_path):
    """Old checkpoints wrote accum.tmp.npy: a leftover (here a folder) broke every later save.
    Unique temporary names cannot collide with it, or with a concurrent writer."""
    folder = tmp_path / ".partial"
    (folder / "arrays.tmp.npz").mkdir(parents=True)
    (folder / "state.tmp.json").mkdir()
    store = Checkpoint(folder, {"spec": "a"})
    acc = np.arange(12.0).reshape(2, 2, 3)
    store.save({"done": 3}, {"acc": acc, "pat_1": acc})
    state, arrays = Checkpoint(folder, {"spec": "a"}).load()
    assert state == {"done": 3} and np.array_equal(arrays["acc"], acc)
    assert np.array_equal(arrays["pat_1"], acc)
    with pytest.warns(PacamWarning, match=r"\(spec changed\)"):
        assert Checkpoint(folder, {"spec": "b"}).load() is None
    with pytest.warns(PacamWarning, match=r"does not fit this capture \(tampered\)"):
        assert Checkpoint(folder, {"spec": "a"}).load(lambda st, ar: "tampered") is None


# --- 2. one writer per --out ---------------------------------------------------------------------
def test_a_second_run_into_the_same_out_is_refused_at_the_start(tmp_path, capsys):
    out = tmp_path / "c"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom pacam_render.io.lock import output_lock\n"
            f"with output_lock({str(out)!r}):\n    print('held', flush=True)\n    time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        t0 = time.perf_counter()
        assert main(["render", "train", "--width", "32", "--height", "24", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "is in use by another pacam run (pid" in err and time.perf_counter() - t0 < 10
        assert not (out / "capture.exr").exists()
        # nor does a psf or a deconvolution write into it (issue 47, low: psf did)
        assert main(["psf", "--velocity", "0", "--out", str(out)]) == 2
        assert "is in use by another pacam run (pid" in capsys.readouterr().err
        assert not (out / "psf.json").exists()
    finally:
        holder.kill()
        holder.wait()
    from pacam_render.io.lock import output_lock

    with output_lock(out), output_lock(out):  # free again once the holder died; re-entrant
        pass
    assert not (out / ".pacam.lock").exists()


# --- 3. determinism ------------------------------------------------------------------------------
def test_split_spp_is_powers_of_two_within_the_limits():
    for spp in (1, 2, 3, 19, 300, 4095, 4096, 10_000, 1_000_000_007):
        passes = split_spp(spp, 76_800)
        assert sum(passes) == spp and all(p & (p - 1) == 0 for p in passes)
        assert max(passes) <= MAX_PASS_SPP and passes == sorted(passes, reverse=True)
    assert max(split_spp(4096, 1280 * 960 * 2)) <= 2**31 // (1280 * 960 * 2)
    with pytest.raises(ValueError):
        split_spp(1, 2**32)


def test_a_chunk_holds_a_few_seconds_of_samples_so_a_signal_is_answered_soon():
    """Issue 56: a 1280x960 step at huge spp rendered 1024 spp chunks (90 s each) and a
    SIGTERM, answered between chunks, came 150 s late. Chunks now hold at most
    MAX_CHUNK_SAMPLES (2^26: about 5 s on the reference machine) where 1 spp allows."""
    assert MAX_CHUNK_SAMPLES == 1 << 26
    for pixels in (1, 76_800, 1280 * 960, 4000 * 3000, 2**26):
        assert max(split_spp(1 << 16, pixels)) * pixels <= MAX_CHUNK_SAMPLES
    assert set(split_spp(1024, 1280 * 960)) == {32}  # 2^26 / 1228800 = 54.6 -> 32
    assert split_spp(3, 2**27) == [1, 1, 1]  # past it: one sample per pixel a chunk


@pytest.mark.render
def test_multi_step_same_seed_renders_are_bit_identical():
    """300 spp over 16 steps (18 or 19 each): one mi.render per step differed by an ulp in a
    few pixels from run to run; power-of-two passes do not."""
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=96, height=72, spp=300, seed=5)
    images = [render_capture(spec, progress=False).image for _ in range(3)]
    assert images[0].any()
    assert all(np.array_equal(images[0], im) for im in images[1:])


# --- 4. SIGINT and SIGTERM -----------------------------------------------------------------------
def _done(state) -> int:
    try:
        return json.loads(state.read_text())["state"]["steps_done"]
    except (OSError, ValueError):
        return 0


DRIVER = """
import os, signal, sys
# a shell's background job starts with SIGINT ignored, and Python then installs no handler:
# the user's Ctrl-C is what the test models
signal.signal(signal.SIGINT, signal.default_int_handler)
import mitsuba as mi
from pacam_render.cli import main

real, calls = mi.render, []
def hooked(*args, **kwargs):  # a signal at a known render: no timing window
    image = real(*args, **kwargs)
    calls.append(1)
    if len(calls) == int(sys.argv[1]):
        os.kill(os.getpid(), int(sys.argv[2]))
    return image
mi.render = hooked
sys.exit(main(sys.argv[3:]))
"""


@pytest.mark.render
def test_sigterm_and_sigint_save_the_finished_steps_and_resume(tmp_path):
    """Each signal arrives at a known render (a driver wraps mi.render), so the test cannot pass
    or fail by timing: the capture saves its finished steps, exits 128 + the signal (143 for
    SIGTERM, 130 for SIGINT; main before issue 37 gave 130 for both), and resumes to the bits
    of an uninterrupted render."""
    out = tmp_path / "c"
    size = ["--width", "64", "--height", "48", "--spp", "64", "--max-step-px", "0.05"]
    cli = ["render", "train", *size, "--checkpoint-every", "0", "--quiet", "--out", str(out)]
    cli += ["--relative-illumination", "off", "--diffraction", "off"]  # the renders counted
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    state = out / ".partial" / "state.json"
    for at, sig in ((6, signal.SIGTERM), (9, signal.SIGINT)):
        before = _done(state)
        argv = [sys.executable, str(driver), str(at), str(int(sig)), *cli]
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 128 + int(sig), proc.stderr  # 143 after SIGTERM, 130 SIGINT
        assert "run the same command again to resume" in proc.stderr
        assert "Traceback" not in proc.stderr
        assert _done(state) > before
    early = subprocess.Popen(
        [sys.executable, "-m", "pacam_render", *cli], stderr=subprocess.PIPE, text=True
    )
    time.sleep(0.3)  # loading the libraries: Ctrl-C there is one line and 130 too
    early.send_signal(signal.SIGINT)
    err = early.communicate(timeout=120)[1]
    assert early.returncode == 130 and "interrupted" in err and "Traceback" not in err, err
    done = subprocess.run(
        [sys.executable, "-m", "pacam_render", *cli], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    meta = json.loads((out / "capture.json").read_text())
    assert meta["resumed_from_step"] > 0 and not (out / ".partial").exists()
    # --quiet still says so (issue 47, low): the capture is partly an earlier run's
    assert f"resumed: {meta['resumed_from_step']} finished step(s)" in done.stderr
    spec = CaptureSpec.geometric(
        scene="train", mode="coded", width=64, height=48, spp=64, max_step_px=0.05
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)
        whole = render_capture(spec, progress=False).image
    assert np.array_equal(read_layer(out / "capture.exr", "capture"), whole.astype(np.float32))


# --- 5. output paths are checked before any work -------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["render", "train"],
        ["psf", "--depth", "500", "--velocity", "0"],
        ["validate-psf", "--quick"],
        ["reproduce", "fig9", "--quick"],
        ["demo"],
    ],
)
@pytest.mark.parametrize("where", ["proc", "under_a_file"])
def test_bad_output_paths_are_refused_before_any_work(argv, where, tmp_path, capsys, monkeypatch):
    import pacam_render.experiments.reproduce as reproduce
    import pacam_render.exposure.direct as capture

    def no_work(*a, **k):
        raise AssertionError("work started before the output path was checked")

    patch_everywhere(monkeypatch, capture, "render_capture", no_work)
    patch_everywhere(monkeypatch, reproduce, "run", no_work)
    (tmp_path / "file").write_text("x")
    bad = "/proc/pacam_x" if where == "proc" else str(tmp_path / "file" / "sub")
    assert main([*argv, "--out", bad]) == 2
    err = capsys.readouterr().err
    assert f"--out {bad}" in err and "Traceback" not in err


def test_deconvolve_checks_its_output_before_reading(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    bad = tmp_path / "file" / "x.png"
    assert main(["deconvolve", str(tmp_path / "none.exr"), "--out", str(bad)]) == 2
    assert f"--out {tmp_path / 'file'} exists and is not a folder" in capsys.readouterr().err


# --- 9. bounded work -----------------------------------------------------------------------------
def test_a_plan_of_too_many_steps_is_refused_at_once():
    spec = CaptureSpec.geometric(max_step_px=1e-6)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match=r"max_steps.*raise max_step_px"):
        plan_steps(np.linspace(0, 45, 17), np.ones(16, bool), 1.0, spec)
    with pytest.raises(ParameterError, match="max_steps"):  # a motion of 1e6 mm/ms
        plan_steps(np.linspace(0, 45, 17), np.ones(16, bool), 1e12, CaptureSpec.geometric())
    with pytest.raises(ParameterError, match="max_steps"):
        plan_steps(np.linspace(0, 45, 17), np.ones(16, bool), np.inf, CaptureSpec.geometric())
    assert time.perf_counter() - t0 < 1.0
    assert (
        len(plan_steps(np.linspace(0, 45, 17), np.ones(16, bool), 1.0, CaptureSpec.geometric()))
        == 96
    )


@pytest.mark.parametrize(
    "argv, match",
    [
        (["render", "train", "--width", "100000", "--height", "75000"], "of memory.*--width"),
        (["render", "train", "--spp", "1000000000"], "--max-samples"),
        (["render", "train", "--max-step-px", "1e-6"], "--max-steps"),
        (["psf", "--depth", "500", "--velocity", "0", "--size", "100001"], "memory.*--size"),
    ],
)
def test_work_beyond_the_limits_is_refused_naming_the_flag(argv, match, tmp_path, capsys):
    t0 = time.perf_counter()
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert __import__("re").search(match, err) and "Traceback" not in err, err
    assert time.perf_counter() - t0 < 30


@pytest.mark.parametrize(
    "flag, value", [("--max-steps", "0"), ("--max-samples", "-5"), ("--checkpoint-every", "-1")]
)
def test_limit_flags_reject_impossible_values(flag, value, tmp_path, capsys):
    assert main(["render", "train", flag, value, "--out", str(tmp_path / "o")]) == 2
    assert f"{flag} must be" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_budget_counts_samples_and_memory():
    check_budget(CaptureSpec.geometric(width=1280, height=960, spp=1024))
    with pytest.raises(ParameterError, match="max_samples"):  # the CLI says --max-samples
        check_budget(CaptureSpec.geometric(width=1280, height=960, spp=1024), max_samples=10**6)
    with pytest.raises(ParameterError, match="the pilot of this noise target"):  # issue 37
        check_budget(CaptureSpec.geometric(width=1280, height=960, spp=1024), 10**6, targeted=True)
    check_budget(CaptureSpec.geometric(width=1280, height=960, spp=1024), 10**7, targeted=True)


# --- 10. spp inflation ---------------------------------------------------------------------------
@pytest.mark.render
def test_more_samples_than_asked_are_reported(tmp_path, capsys):
    out = tmp_path / "c"
    args = ["render", "train", "--width", "64", "--height", "48", "--spp", "2", "--quiet"]
    assert main([*args, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    meta = json.loads((out / "capture.json").read_text())
    assert meta["effective_spp"] > 2 and meta["spec"]["spp"] == 2
    assert f"take {meta['effective_spp']} spp where 2 were asked" in err
    assert any("where 2 were asked" in n for n in meta["notes"])


# --- 11. physics that cannot be ------------------------------------------------------------------
def test_physical_limits_hold_in_every_entry_point(tmp_path, capsys):
    pitch = prototype().lcos_pitch_mm
    with pytest.raises(ParameterError, match=r"object_depth_mm must be >= 100 mm"):
        prototype().with_(object_depth_mm=5.0)
    with pytest.raises(ParameterError, match=r"R_mm must be >= 1 LCoS px"):
        CameraDesign(R_mm=0.0014 * pitch)
    with pytest.raises(ParameterError, match=r"exposure_ms must be >= 0.01 ms"):
        prototype().with_(exposure_ms=1e-6)
    for argv, flag in [
        (["design", "--depth", "5"], "--depth must be >= 100 mm"),
        (["design", "--exposure", "1e-6"], "--exposure must be >= 0.01 ms"),
        (["psf", "--depth", "5", "--velocity", "0", "--out", str(tmp_path / "p")], "--depth"),
    ]:
        assert main(argv) == 2
        assert flag in capsys.readouterr().err
    assert "355.6 per s" in design_report(prototype())  # 16 patterns in 45 ms, computed


# --- 12. truncated kernels -----------------------------------------------------------------------
def test_a_heavily_truncated_psf_is_refused(tmp_path, capsys):
    out = tmp_path / "p"
    assert main(["psf", "--depth", "500", "--velocity", "1e6", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "99.99" in err and "more than the 1% allowed" in err and "--size" in err
    assert not any(out.glob("psf*"))


# --- 13. saturation ------------------------------------------------------------------------------
@pytest.mark.render
def test_saturation_is_warned_and_recorded(tmp_path, capsys):
    args = ["render", "train", "--mode", "short", "--width", "32", "--height", "24", "--spp", "4"]
    args += ["--sensor", "grasshopper-icx285", "--quiet"]
    # 1e9 photons/px/ms: the most --light-level takes (issue 56), far past every full well
    assert main([*args, "--light-level", "1e9", "--out", str(tmp_path / "hot")]) == 0
    err = capsys.readouterr().err
    hot = json.loads((tmp_path / "hot" / "capture.json").read_text())
    assert hot["sensor"]["saturated_fraction"] > 0.99 and "saturate the sensor" in err
    assert any("saturate" in n for n in hot["notes"])
    assert main([*args, "--out", str(tmp_path / "ok")]) == 0
    assert "saturate" not in capsys.readouterr().err
    ok = json.loads((tmp_path / "ok" / "capture.json").read_text())
    assert ok["sensor"]["saturated_fraction"] < 1e-3


# --- 14-16. deconvolution traps ------------------------------------------------------------------
def _methods() -> list[str]:
    """METHODS less the optional ones whose package is missing."""
    import importlib.util

    optional = {"bm3d": "bm3d", "pnp": "scico"}
    return [m for m in METHODS if importlib.util.find_spec(optional.get(m, "numpy")) is not None]


@pytest.mark.parametrize("method", _methods())
def test_every_method_returns_zero_for_an_all_zero_image(method):
    k = np.ones((5, 5))
    for shape in ((32, 32), (32, 32, 3)):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # no RuntimeWarning (0/0) either
            out = deconvolve(np.zeros(shape), k, method)
        assert out.shape == shape and np.array_equal(out, np.zeros(shape))


def test_wiener_keeps_a_constant_image_constant():
    """A noiseless constant image: the estimated sigma is ~1e-34, which once left the box
    kernel's spectral zeros unregularised (values from -0.3 to 0.8 on a 0.3 image)."""
    out = deconvolve(np.full((32, 32, 3), 0.3), np.ones((5, 5)), "wiener")
    assert np.allclose(out, 0.3, atol=1e-6)


def test_cli_deconvolve_of_an_all_zero_capture(tmp_path):
    cap = write_exr(tmp_path / "capture.exr", {"capture": np.zeros((24, 32, 3))})
    np.save(tmp_path / "k.npy", np.ones((5, 5)))
    for method in _methods():
        for suffix in (".exr", ".png"):
            out = tmp_path / f"{method}{suffix}"
            argv = ["deconvolve", str(cap), "--psf", str(tmp_path / "k.npy"), "--method", method]
            assert main([*argv, "--noise-sigma", "0.01", "--out", str(out)]) == 0
    assert np.array_equal(read_layer(tmp_path / "wiener.exr", "deconvolved"), np.zeros((24, 32, 3)))


def test_deconvolve_explains_an_object_npy_psf_and_a_missing_rendered_psf(tmp_path, capsys):
    cap = write_exr(tmp_path / "capture.exr", {"capture": np.ones((24, 32, 3))})
    np.save(tmp_path / "obj.npy", np.array([np.ones((3, 3)), "x"], dtype=object))
    argv = ["deconvolve", str(cap), "--out", str(tmp_path / "o.exr"), "--psf"]
    assert main([*argv, str(tmp_path / "obj.npy")]) == 2
    err = capsys.readouterr().err
    assert "holds Python objects" in err and "Traceback" not in err
    assert main([*argv, "rendered"]) == 2
    assert f"pacam psf --like {cap} --velocity 0 --render" in capsys.readouterr().err


# --- 17. options that do nothing say so ----------------------------------------------------------
@pytest.mark.render
def test_ignored_options_get_a_note(tmp_path):
    tiny = {"width": 32, "height": 24, "spp": 4}
    with pytest.warns(PacamWarning, match="cover_px_per_ms has no effect in normal mode"):
        cap = render_capture(
            CaptureSpec.geometric(mode="normal", cover_px_per_ms=1.0, **tiny), progress=False
        )
    assert "cover_px_per_ms" in cap.record.notes[0]
    with pytest.warns(PacamWarning, match="per_pattern keeps nothing"):
        render_capture(
            CaptureSpec.geometric(mode="reference", per_pattern=True, **tiny), progress=False
        )
    with warnings.catch_warnings(record=True) as caught:  # coded uses the cover: no note on it
        warnings.simplefilter("always", PacamWarning)
        render_capture(
            CaptureSpec.geometric(mode="coded", cover_px_per_ms=1.0, **{**tiny, "spp": 16}),
            progress=False,
        )
    assert caught and not any("cover_px_per_ms" in str(w.message) for w in caught)
    xml = tmp_path / "s.xml"
    xml.write_text(
        "<scene version='3.0.0'><sensor type='perspective'/>"
        "<shape type='sphere' id='ball'><point name='center' x='0' y='0' z='800'/></shape>"
        "</scene>"
    )
    from pacam_render.scenes import load_scene

    with pytest.warns(PacamWarning, match="the <sensor> of s.xml is not used"):
        load_scene(str(xml))


# --- 18. messages use the flags ------------------------------------------------------------------
def test_cli_messages_name_the_flags_the_user_typed(tmp_path, capsys):
    assert main(["render", "train", "--max-step-px", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--max-step-px must be > 0" in capsys.readouterr().err
    assert main(["render", "train", "--cover", "-1", "--out", str(tmp_path / "o")]) == 2
    assert "--cover must be > 0" in capsys.readouterr().err
    assert main(["design", "--max-velocity", "3", "--depth", "1000", "--r-px", "100"]) == 2
    err = capsys.readouterr().err
    assert "side=" not in err and "r_px" not in err and "focus" in err
