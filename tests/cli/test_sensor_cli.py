"""``pacam sensor`` (issue 27 item 6): the sensor on a capture already rendered gives what
``pacam render --sensor`` gives, in distribution, and refuses bad input naming the flag."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.io.exr import read_exr

pytestmark = pytest.mark.render
PRESET, LIGHT = "grasshopper-icx285", "3000"
TINY = ["train", "--mode", "coded", "--width", "64", "--height", "48", "--spp", "8", "--quiet"]


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    """The same capture rendered without a sensor and with one (seed 5 for both)."""
    root = tmp_path_factory.mktemp("sensor_cli")
    plain, direct = root / "plain", root / "direct"
    assert main(["render", *TINY, "--seed", "5", "--out", str(plain)]) == 0
    sensor = ["--sensor", PRESET, "--light-level", LIGHT]
    assert main(["render", *TINY, "--seed", "5", *sensor, "--out", str(direct)]) == 0
    return plain, direct


def test_sensor_on_a_capture_matches_render_sensor_in_distribution(captures, tmp_path, capsys):
    """Another seed's noisy layer: its mean within 2 % and the sigma of noisy - capture within
    5 % of render --sensor's (27 648 values: the sigma's standard error is 0.4 %), not the
    same draws; the same three files, and the sensor in the JSON."""
    plain, direct = captures
    out = tmp_path / "sensed"
    argv = ["sensor", str(plain / "capture.exr"), "--sensor", PRESET, "--light-level", LIGHT]
    assert main([*argv, "--seed", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert f"{PRESET} at 3000 photons/px/ms" in printed and "noisy" in printed
    assert sorted(p.name for p in out.iterdir()) == ["capture.exr", "capture.json", "capture.png"]
    ours, theirs = read_exr(out / "capture.exr"), read_exr(direct / "capture.exr")
    np.testing.assert_array_equal(ours["capture"], theirs["capture"])
    assert ours["noisy"].mean() == pytest.approx(theirs["noisy"].mean(), rel=0.02)
    a, b = ours["noisy"] - ours["capture"], theirs["noisy"] - theirs["capture"]
    assert a.std() == pytest.approx(b.std(), rel=0.05)
    assert np.mean(a == b) < 0.5
    rec, ref = (json.loads((d / "capture.json").read_text()) for d in (out, direct))
    assert rec["sensor"]["preset"] == PRESET and rec["sensor"]["seed"] == 1
    assert rec["noise_sigma"] == pytest.approx(ref["noise_sigma"], rel=0.02)
    assert set(ours) >= {"sharp", "depth", "object_id", "velocity", "raw", "noisy"}


def test_the_captures_own_seed_gives_render_sensor_bit_for_bit(captures, tmp_path):
    plain, direct = captures
    out = tmp_path / "same"
    argv = ["sensor", str(plain), "--sensor", PRESET, "--light-level", LIGHT, "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    ours, theirs = read_exr(out / "capture.exr"), read_exr(direct / "capture.exr")
    np.testing.assert_array_equal(ours["noisy"], theirs["noisy"])
    np.testing.assert_array_equal(ours["raw"], theirs["raw"])


def test_a_capture_with_a_sensor_gets_it_replaced_with_a_note(captures, tmp_path, capsys):
    _, direct = captures
    out = tmp_path / "again"
    argv = ["sensor", str(direct), "--sensor", PRESET, "--light-level", "300", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    assert (
        f"note: the capture's sensor ({PRESET}) is replaced by {PRESET}" in capsys.readouterr().err
    )
    rec = json.loads((out / "capture.json").read_text())
    assert rec["sensor"]["light_level_photons_per_px_per_ms"] == 300.0


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--sensor", "nope"], "--sensor: unknown sensor preset 'nope'"),
        (
            ["--sensor", PRESET, "--light-level", "-1"],
            "--light-level must be in [1e-06, 1e+09] photons/px/ms",
        ),
        (["--sensor", PRESET, "--light-level", "nan"], "--light-level must be a finite number"),
    ],
)
def test_bad_input_is_refused_naming_the_flag(captures, tmp_path, capsys, extra, message):
    plain, _ = captures
    out = tmp_path / "o"
    assert main(["sensor", str(plain), *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and not out.exists()


def test_a_missing_capture_an_input_folder_and_an_existing_output_are_refused(
    captures, tmp_path, capsys
):
    plain, direct = captures
    flags = ["--sensor", PRESET]
    assert main(["sensor", str(tmp_path / "none.exr"), *flags, "--out", str(tmp_path / "o")]) == 2
    assert "no capture at" in capsys.readouterr().err
    assert main(["sensor", str(plain), *flags, "--out", str(plain)]) == 2
    assert "holds the input capture" in capsys.readouterr().err
    assert main(["sensor", str(plain), *flags, "--out", str(direct)]) == 2
    assert "already holds a capture; pass --force" in capsys.readouterr().err
