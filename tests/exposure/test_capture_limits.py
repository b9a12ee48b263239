"""Issue 37 items 12, 13 and 16: the sample limit counts what is really rendered (the passes as
the time steps round them, and a noise target's pilot) before any render; a noise target out
of reach within it is said at once after the pilot, with what it would take; and a resumed
capture's seconds count every session's work.

References: the rounding the render itself notes ("2 passes of at least 4 spp per time step
take 128 spp where 1 were asked"), sigma^2 ~ 1 / spp, and the seconds of a first session
slowed on purpose.
"""

from __future__ import annotations

import json
import time

import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import CaptureInterrupted, render_capture
from pacam_render.exposure.estimate import AbsoluteTarget
from pacam_render.exposure.spec import CaptureSpec
from tests.patching import patch_everywhere

SMALL = {"scene": "train", "mode": "coded", "width": 48, "height": 32}
"""The train on a 48 x 32 sensor: 16 time steps per pass, at least 4 spp each (ldsampler)."""
TRAIN_WINDOW = {"width": 1280, "height": 960, "crop": (300, 600, 48, 32), "max_step_px": 2.0}


def _no_render(monkeypatch):
    import pacam_render.render.passes as passes

    def refuse(*args, **kwargs):
        raise AssertionError("rendered before refusing")

    patch_everywhere(monkeypatch, passes, "render_passes", refuse)


# --- 13. the limit counts what is rendered ------------------------------------------------------
def test_the_limit_counts_the_spp_the_time_steps_round_to(monkeypatch):
    """--spp 1 rendered 128 spp (2 passes x 16 steps x 4 spp) under a limit of 64 spp with rc 0;
    now it is refused once the steps are planned, before any render."""
    _no_render(monkeypatch)
    spec = CaptureSpec.geometric(**SMALL, spp=1)
    with pytest.raises(ParameterError) as err:
        render_capture(spec, progress=False, truth=False, max_samples=64 * 48 * 32)
    words = str(err.value)
    assert "2 passes of at least 4 spp per time step (ldsampler), 16 steps, take 128 spp" in words
    assert "where `spp` 1 was asked; 128 spp x 48 x 32 px): 1.966e+05, above the limit of " in words
    assert "(max_samples raises it)" in words


def test_a_noise_targets_pilot_is_counted_before_it_renders(monkeypatch):
    _no_render(monkeypatch)
    spec = CaptureSpec.geometric(**SMALL)
    with pytest.raises(
        ParameterError,
        match=r"the pilot of this noise target \(2 passes of at "
        r"least 4 spp per time step \(ldsampler\), 16 steps; 128 spp x 48 x 32",
    ):
        render_capture(
            spec, progress=False, truth=False, target=AbsoluteTarget(1e-3),
            max_samples=64 * 48 * 32,
        )  # fmt: skip


def test_cli_refuses_the_rounded_spp_before_any_file(tmp_path, capsys):
    """The issue's command: --spp 1 --max-samples 3072 on 48 x 32 px. The least that 2 passes
    of the sampler's 4 spp take is 8 spp = 12288 samples: refused before the scene loads."""
    out = tmp_path / "c"
    argv = ["render", "train", "--width", "48", "--height", "32", "--out", str(out)]
    assert main([*argv, "--spp", "1", "--max-samples", "3072"]) == 2
    err = capsys.readouterr().err
    assert "2 passes of at least 4 spp (ldsampler), take 8 spp where --spp 1 was asked" in err
    assert "above the limit of 3072 (--max-samples raises it); or lower --passes" in err
    assert main([*argv, "--noise-target", "0.01", "--max-samples", "3072"]) == 2
    assert "the pilot of this noise target (2 passes of at least 4 spp" in capsys.readouterr().err
    assert not out.exists()


# --- 12. a target out of reach is said after the pilot -----------------------------------------
@pytest.mark.render
def test_a_target_out_of_reach_is_refused_after_the_pilot_and_resumes_with_a_larger_limit(
    tmp_path,
):
    """After the pilot, a target that the pilot predicts beyond max_samples is refused at once,
    naming max_samples, the samples and the seconds it would take; the pilot is kept, and the
    same capture with a larger limit resumes from it."""
    spec = CaptureSpec.geometric(scene="train", mode="coded", seed=3, **TRAIN_WINDOW)
    goal = AbsoluteTarget(2.5e-4)
    part = tmp_path / "c" / ".partial"
    pilot_spp = 2 * 4 * 32  # two passes of one 4 spp render per step, 32 steps
    limit = 48 * 32 * (pilot_spp + 64)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError) as err:
        render_capture(spec, partial_dir=part, progress=False, truth=False, target=goal,
                       max_samples=limit)  # fmt: skip
    words = str(err.value)
    assert words.startswith(f"the noise target is out of reach within max_samples {limit}: ")
    assert f"the pilot's {pilot_spp} spp give a Monte Carlo sigma of " in words
    assert "so the target takes at least " in words and " s at the pilot's pace)" in words
    assert f"where max_samples allows {pilot_spp + 64} spp; raise max_samples to " in words
    assert f"the pilot is saved in {part}" in words
    state = json.loads((part / "state.json").read_text())["state"]
    assert state["schedule"]["phase"] == "pilot" and state["steps_done"] == 64
    assert state["seconds"] <= time.perf_counter() - t0
    cap = render_capture(spec, partial_dir=part, progress=False, truth=False, target=goal)
    err = cap.record.render_error
    assert cap.record.resumed_from_step == 64 and err.target_met


@pytest.mark.render
def test_cli_says_at_once_that_a_target_is_out_of_reach(tmp_path, capsys):
    """--noise-target 1e-9 planned all of --max-samples (the default 2^35, 1.5 h) in silence;
    now the command stops after the pilot, exit 2, naming --max-samples and what the target
    takes. (A limit of 1e6 samples keeps the old behaviour, rendering up to it, short.)"""
    out = tmp_path / "c"
    argv = ["render", "train", "--width", "16", "--height", "12", "--noise-target", "1e-9"]
    argv += ["--max-samples", "1000000", "--quiet", "--no-truth", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "error: the noise target is out of reach within --max-samples 1000000: " in err
    assert "raise --max-samples to " in err and "relax --noise-target" in err
    assert "Traceback" not in err and (out / ".partial" / "state.json").is_file()


# --- 16. a resumed capture's seconds ------------------------------------------------------------
@pytest.mark.render
def test_a_resumed_captures_seconds_count_every_session(tmp_path, monkeypatch):
    """A first session slowed to at least 2 s stops after 4 steps; the resumed capture's
    render_error.seconds and render_seconds hold those seconds besides its own (they held the
    last session's alone)."""
    import pacam_render.render.passes as passes

    real = passes.render_passes

    def slow(*args, **kwargs):
        time.sleep(0.5)
        return real(*args, **kwargs)

    spec = CaptureSpec.geometric(scene="train", mode="coded", width=40, height=30, spp=16, seed=2)
    part = tmp_path / "c" / ".partial"
    patch_everywhere(monkeypatch, passes, "render_passes", slow)
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, truth=False, stop_after_steps=4)
    patch_everywhere(monkeypatch, passes, "render_passes", real)
    carried = json.loads((part / "state.json").read_text())["state"]["seconds"]
    assert carried >= 2.0
    t0 = time.perf_counter()
    cap = render_capture(spec, partial_dir=part, progress=False, truth=False)
    second = time.perf_counter() - t0
    assert cap.record.resumed_from_step == 4
    seconds = cap.record.render_error.seconds
    assert carried < seconds <= carried + second + 0.01
    assert carried < cap.record.render_seconds <= carried + second + 0.01
