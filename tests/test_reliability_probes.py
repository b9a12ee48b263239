"""Issue 26's probes 7-10 and 12 (and two of its "Low" items), one test each: bad input is
refused before any work, with an error naming the parameter or flag and its range."""

from __future__ import annotations

import http.server
import json
import re
import socketserver
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.limits import PacamWarning
from pacam_render.sensor.model import SensorModel
from pacam_render.study import engine
from tests.patching import patch_everywhere


def _no_render(monkeypatch):
    """Make any capture render fail loudly: the refusals below must come before one."""
    import pacam_render.exposure.direct as capture

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before refusing")

    patch_everywhere(monkeypatch, capture, "render_capture", refuse)


def _refuse(why: str):
    """A stand-in for a long computation that the refusals below must come before."""

    def refuse(*args, **kwargs):
        raise AssertionError(why)

    return refuse


# --- 7. extreme sensor presets -------------------------------------------------------------------
@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("K", 1e-308, r"K must be in \[1e-06, 1e\+06\] DN/e-"),
        ("read_noise_e", 1e308, r"read_noise_e must be in \[0, 1e\+06\] e-"),
        ("full_well_e", 1e-300, r"full_well_e must be in \[1, 1e\+09\] e-"),
        ("dsnu_e", 1e300, r"dsnu_e must be in \[0, 1e\+06\] e-"),
        ("dark_current_e_per_s", 1e300, r"dark_current_e_per_s must be in \[0, 1e\+09\] e-/s"),
    ],
)
def test_extreme_sensor_parameters_are_refused_with_their_range(key, value, match):
    with pytest.raises(ParameterError, match=match):
        SensorModel.from_preset("grasshopper-icx285", **{key: value})


def test_an_extreme_preset_file_is_refused_before_the_render(tmp_path, capsys, monkeypatch):
    preset = tmp_path / "odd.json"
    preset.write_text(json.dumps({"base": "grasshopper-icx285", "K": 1e-308}))
    _no_render(monkeypatch)
    out = tmp_path / "out"
    argv = ["render", "train", "--width", "16", "--height", "12", "--spp", "1"]
    assert main([*argv, "--sensor", str(preset), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"preset file {preset}: K must be in [1e-06, 1e+06] DN/e-" in err
    assert not out.exists()


# --- 8. a --scheduler that is not Dask -----------------------------------------------------------
class _HttpAnswer(socketserver.BaseRequestHandler):
    """Answers any request at once with an HTTP error, and keeps the connection open."""

    def handle(self):
        self.request.recv(4096)
        self.request.sendall(b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
        self.request.recv(4096)  # until the client hangs up


@pytest.fixture(params=["http.server", "answers-http"])
def not_dask(request):
    """A loopback service that is not a Dask scheduler: Python's http.server (it waits for a
    request line that never comes) or one that answers in HTTP at once (old: MemoryError)."""
    if request.param == "http.server":
        server = http.server.ThreadingHTTPServer(
            ("127.0.0.1", 0), http.server.BaseHTTPRequestHandler
        )
    else:
        server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), _HttpAnswer)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def _bounded(fn, limit_s: float = 60.0):
    """``fn()``'s exception, or a failure if it takes more than ``limit_s`` (a hang)."""
    caught: list[BaseException] = []

    def call():
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            caught.append(exc)

    thread = threading.Thread(target=call, daemon=True)
    thread.start()
    thread.join(limit_s)
    assert not thread.is_alive(), f"still waiting after {limit_s} s"
    return caught[0] if caught else None


def test_a_scheduler_that_is_not_dask_is_a_clear_error(not_dask, monkeypatch):
    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)
    exc = _bounded(lambda: engine.run_tasks(abs, [1, 2], lambda t, r: None, scheduler=not_dask))
    assert isinstance(exc, ParameterError), repr(exc)
    assert str(exc).startswith(f"`scheduler` {not_dask}: no Dask scheduler answered within 1 s")


@pytest.mark.parametrize("not_dask", ["answers-http"], indirect=True)  # main() needs the main
def test_study_refuses_a_scheduler_that_is_not_dask_before_any_work(  # thread: no hang test
    not_dask, tmp_path, capsys, monkeypatch
):
    monkeypatch.setattr(engine, "CONNECT_TIMEOUT_S", 1.0)
    out = tmp_path / "out"
    argv = ["study", "crossover", "--quick", "--scheduler", not_dask, "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"pacam study: error: --scheduler {not_dask}: no Dask scheduler")
    assert "\n" not in err and "Traceback" not in err
    assert not out.exists()


# --- 9. pacam psf bounds its work ----------------------------------------------------------------
PSF = ["psf", "--depth", "500", "--velocity", "0.1"]


def test_psf_render_beyond_the_sample_limit_is_refused_naming_the_flag(
    tmp_path, capsys, monkeypatch
):
    import pacam_render.psf_render.render as psf_render

    renderer = psf_render.PSFRenderer
    monkeypatch.setattr(renderer, "_render_passes", _refuse("rendered before refusing"))
    out = tmp_path / "out"
    argv = [*PSF, "--render", "--film", "crop", "--spp", "1000000", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "above the limit of 34359738368 (--max-samples raises it)" in err
    assert "whole 1280x960 film" in err and not out.exists()


def test_psf_of_a_huge_sensor_is_refused_before_computing_the_kernel(tmp_path, capsys, monkeypatch):
    import pacam_render.cli.psf as cli_psf

    monkeypatch.setattr(cli_psf, "design_psf", _refuse("computed the kernel before refusing"))
    out = tmp_path / "out"
    assert main([*PSF, "--width", "100000000", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "falls outside the 2049x2049 kernel" in err and "lower --width/--height" in err
    assert not out.exists()


@pytest.mark.render
@pytest.mark.parametrize("how", ["signal", "wrapped"])
def test_psf_interrupted_while_rendering_writes_nothing(how, tmp_path, capsys, monkeypatch):
    """SIGINT after the second render call (Python's handler), or a KeyboardInterrupt that
    Dr.Jit wrapped in a RuntimeError (a Ctrl-C inside the render): exit 130, one line."""
    import os
    import signal

    import mitsuba as mi

    real, calls = mi.render, []

    def render(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2 and how == "wrapped":
            raise RuntimeError("drjit.custom(...): error") from KeyboardInterrupt()
        image = real(*args, **kwargs)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGINT)
        return image

    monkeypatch.setattr(mi, "render", render)
    # a shell's background job starts with SIGINT ignored; the test models a user's Ctrl-C
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    out = tmp_path / "out"
    argv = [*PSF, "--render", "--spp", "16", "--quiet", "--out", str(out)]
    try:
        assert main(argv) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(calls) == 2
    assert capsys.readouterr().err.strip() == "pacam psf: interrupted"
    assert not out.exists() or not any(out.iterdir())


# --- 10. a --schedule that the mode does not show -------------------------------------------------
def _schedule(path):
    doc = {
        "centres_mm": [[x, 0.0] for x in np.linspace(-1.5, 1.5, 16)],
        "radius_mm": 1.0,
        "focus_distance_mm": 750.0,
        "n_patterns": 16,
    }
    path.write_text(json.dumps(doc))
    return str(path)


@pytest.mark.render
@pytest.mark.parametrize(
    ("mode", "match"),
    [
        (
            "normal",
            "openings and focus are not used in normal mode .*: only its exposure and radius",
        ),
        ("reference", "openings, focus, radius and exposure are not used in .*: it has no effect"),
        ("coded", None),
    ],
)
def test_a_schedule_the_mode_does_not_show_is_noted_and_recorded_unused(mode, match, tmp_path):
    from pacam_render.exposure.direct import render_capture
    from pacam_render.exposure.spec import CaptureSpec

    spec = CaptureSpec.geometric(
        mode=mode, width=32, height=24, spp=4, schedule=_schedule(tmp_path / "s")
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PacamWarning)
        rec = render_capture(spec, progress=False, truth=False).record.to_json()
    notes = [str(w.message) for w in caught if "`schedule`" in str(w.message)]
    if match is None:  # coded shows the schedule: no note, and its camera has the openings
        assert not notes and rec["optics"]["schedule"] == "designed"
        return
    assert len(notes) == 1 and re.search(match, notes[0]) and notes[0] in rec["notes"]
    assert rec["camera"]["pattern_centres_mm"] is None and rec["optics"]["schedule"] != "designed"
    assert rec["camera"]["name"].endswith("not used")


# --- 12. flags checked before any work (and the "Low" sizes and --out) ---------------------------
@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["demo", "--height", "100"], "--width and --height go together"),
        (["demo", "--width", "320"], "--width and --height go together"),
        (
            ["validate-scene", "train", "--crop", "0,0,10,10"],
            "--crop window must be at least 32x32",
        ),
        (["validate-scene", "train", "--quantum", "1e-9"], r"--quantum must be in \[0.05, 4\] px"),
        (["render", "train", "--width", "0"], "--width must be a positive number of px, got 0"),
        (["psf", *PSF[1:], "--height", "0"], "--height must be a positive number of px, got 0"),
        (["validate-scene", "train", "--width", "0"], "--width must be a positive number"),
    ],
)
def test_flags_are_refused_before_any_work(argv, match, tmp_path, capsys, monkeypatch):
    import pacam_render.experiments.demo as demo
    import pacam_render.experiments.validate_scene as vs

    _no_render(monkeypatch)
    patch_everywhere(monkeypatch, demo, "run_demo", _refuse("the demo ran before refusing"))
    patch_everywhere(monkeypatch, vs, "run", _refuse("validate-scene ran before refusing"))
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err) and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("argv", [["render", "train"], PSF, ["validate-psf", "--quick"]])
def test_an_empty_out_is_refused(argv, tmp_path, capsys, monkeypatch):
    import pacam_render.experiments.validate_psf as validate_psf

    monkeypatch.chdir(tmp_path)  # the old code wrote here
    _no_render(monkeypatch)
    patch_everywhere(monkeypatch, validate_psf, "run", _refuse("validate-psf ran before refusing"))
    assert main([*argv, "--out", ""]) == 2
    assert "--out must name a folder or file, got ''" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


# --- the "Low" items: one-line errors, honest messages, --force and interrupts --------------------
def _one_line_error(capsys, argv, match: str) -> str:
    """``main(argv)`` exits 2 with one line (no traceback) matching ``match``; returns it."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert re.search(match, err), err
    assert "\n" not in err and "Traceback" not in err
    return err


def test_design_refuses_an_absurd_exposure_in_one_line(capsys):
    err = _one_line_error(capsys, ["design", "--exposure", "1e300"], r"<= 100000 ms")
    assert err.startswith("pacam design: error:")
    argv = ["design", "--exposure", "1e300", "--max-velocity", "1"]
    assert "--exposure" in _one_line_error(capsys, argv, r"--exposure must be <= 100000 ms")


def _tiny_capture(path):
    """A capture EXR that deconvolve reads (a 'capture' layer only), no JSON beside it."""
    from pacam_render.io.exr import write_exr

    write_exr(path, {"capture": np.full((8, 8, 3), 0.5, np.float32)})
    return str(path)


@pytest.mark.parametrize(("content", "match"), [(None, "not readable"), ((0, 0), "empty array")])
def test_an_empty_npy_psf_is_refused_in_one_line(content, match, tmp_path, capsys):
    psf = tmp_path / "k.npy"
    psf.write_bytes(b"") if content is None else np.save(psf, np.zeros(content))
    capture = _tiny_capture(tmp_path / "c.exr")
    out = tmp_path / "out"
    argv = ["deconvolve", capture, "--psf", str(psf), "--method", "wiener", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"--psf file {psf} " in err and match in err and "Traceback" not in err


def test_an_absurd_noise_sigma_is_refused_naming_the_flag_and_range(tmp_path, capsys):
    capture = _tiny_capture(tmp_path / "c.exr")
    out = tmp_path / "out"
    argv = ["deconvolve", capture, "--psf", "analytic", "--method", "wiener", "--out", str(out)]
    for sigma in ("1e300", "nan", "-1"):
        match = r"--noise-sigma must be in \[0, 1000\] \(the layer's units: up to 1000x its peak"
        _one_line_error(capsys, [*argv, "--noise-sigma", sigma], match)
        assert not out.exists()


def _fake_tasks(monkeypatch, interrupt_at: int | None = None):
    """Study tasks that score every point ``ok`` without rendering; the ``interrupt_at``-th
    task raises what a Ctrl-C inside a serial capture raises."""
    import pacam_render.study as study
    from pacam_render.exposure.integrate import CaptureInterrupted
    from pacam_render.study.point import point_row

    calls = []

    def run_task(task):
        calls.append(task)
        if len(calls) == interrupt_at:
            raise CaptureInterrupted("interrupted (SIGINT) before any time step finished; "
                                     "nothing to resume")  # fmt: skip
        return [point_row(p, {}, "ok", 0.0, 0.0) for p in task.points]

    monkeypatch.setattr(study, "run_task", run_task)
    monkeypatch.setattr(study, "write_report", lambda spec, out: [], raising=False)
    return calls


def _study_toml(tmp_path, body='[grid]\nseed = [0, 1, 2]\nmethod = ["none"]\n'):
    path = tmp_path / "s.toml"
    path.write_text("[render]\nwidth = 32\nheight = 24\nnoise_ratio = false\nspp = 4\n" + body)
    return str(path)


def test_an_interrupted_serial_study_says_how_many_points_are_saved(tmp_path, capsys, monkeypatch):
    _fake_tasks(monkeypatch, interrupt_at=2)
    out = tmp_path / "out"
    argv = ["study", _study_toml(tmp_path), "--workers", "0", "--quiet", "--out", str(out)]
    assert main(argv) == 130
    err = capsys.readouterr().err.strip()
    assert err == (
        f"pacam study: interrupted (SIGINT) before any time step finished; 1 of 3 points are "
        f"saved in {out / 'results.csv'}: run the same command again to resume"
    )
    assert (out / "results.csv").read_text().count("\n") == 2  # the header and point 0


@pytest.mark.parametrize(
    "garbage", [b"\x00\xff garbage\n", b"garbage\n", b"point,status\n1.5,ok\n", b"point\n-1\n"]
)
def test_a_garbage_results_csv_is_refused_naming_the_file(garbage, tmp_path, capsys, monkeypatch):
    _fake_tasks(monkeypatch)
    out = tmp_path / "out"
    argv = ["study", _study_toml(tmp_path), "--workers", "0", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    (out / "results.csv").write_bytes(garbage)
    _one_line_error(capsys, argv, rf"{out / 'results.csv'} is unreadable .*; pass --force")


@pytest.mark.parametrize("body", ["", "[study]\nname = 'x'\n", "[grid]\n"])
def test_a_study_without_points_is_refused(body, tmp_path, capsys, monkeypatch):
    _fake_tasks(monkeypatch, interrupt_at=1)  # would fail the test with 130 if it ran
    toml = tmp_path / "s.toml"
    toml.write_text(body)
    out = tmp_path / "out"
    argv = ["study", str(toml), "--out", str(out)]
    _one_line_error(capsys, argv, r"the study file names no points: give a \[grid\] table")
    assert not out.exists()


@pytest.mark.parametrize(
    ("render", "match"),
    [
        ("max_step_px = -1", r"\[render\] max_step_px must be > 0 px"),
        ("noise_ratio = 20", r"\[render\] noise_ratio must be a number in \(0, 10\]"),
    ],
)
def test_study_errors_name_the_toml_key_not_the_flag(render, match, tmp_path, capsys):
    toml = tmp_path / "s.toml"
    toml.write_text(f"[render]\n{render}\n[grid]\nseed = [0]\n")
    err = _one_line_error(capsys, ["study", str(toml), "--out", str(tmp_path / "out")], match)
    assert "--max-step-px" not in err and "--noise-ratio" not in err


def test_render_force_discards_a_stale_checkpoint(tmp_path, capsys, monkeypatch):
    import pacam_render.exposure.direct as capture

    out = tmp_path / "out"
    stale = out / ".partial"
    stale.mkdir(parents=True)
    (stale / "state.json").write_text("{}")
    seen = []

    def render_capture(spec, partial_dir=None, **kw):
        seen.append(Path(partial_dir).exists())
        raise ParameterError("stop here")

    patch_everywhere(monkeypatch, capture, "render_capture", render_capture)
    argv = ["render", "train", "--width", "16", "--height", "12", "--spp", "1", "--force"]
    assert main([*argv, "--out", str(out)]) == 2
    assert seen == [False]
    err = capsys.readouterr().err
    assert f"note: --force: discarded the finished steps of an earlier run in {stale}" in err


def test_an_interrupted_optimize_leaves_no_empty_folder(tmp_path, capsys, monkeypatch):
    import pacam_render.optimize.run as run

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    patch_everywhere(monkeypatch, run, "run_optimize", interrupted)
    out = tmp_path / "out"
    assert main(["optimize", "--max-velocity", "1", "--quick", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip() == "pacam optimize: interrupted"
    assert not out.exists()
