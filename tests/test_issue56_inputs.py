"""Issue 56, stores that cannot lie: inputs from outside refused cleanly before they cost
anything (each test fails on the main before it): a schedule nested 10^5 deep, a PNG mask or
scene texture declaring 60000x60000 px, and a render-time history that is not a bounded file."""

from __future__ import annotations

import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.model.schedule_file import read_schedule

DEPTH = 100_000  # the depth: far past Python's recursion limit (1000)


@pytest.fixture(params=["array", "object"])
def deep_schedule(tmp_path, request):
    """A schedule.json nested DEPTH levels deep: ``[[[...]]]`` or ``{"a": {"a": ...}}``."""
    path = tmp_path / "deep.json"
    if request.param == "array":
        path.write_text("[" * DEPTH + "]" * DEPTH)
    else:
        path.write_text('{"a":' * DEPTH + "1" + "}" * DEPTH)
    return path


def test_a_schedule_nested_too_deep_is_refused_naming_it(deep_schedule):
    with pytest.raises(ParameterError, match=f"`schedule` {deep_schedule} is nested too deep"):
        read_schedule(deep_schedule)


@pytest.mark.parametrize(
    "command",
    [
        ["design"],
        ["render", "train", "--width", "64", "--height", "48", "--spp", "4", "--quiet"],
        ["lightfield", "train", "--width", "64", "--height", "48", "--spp", "4", "--quiet"],
    ],
    ids=["design", "render", "lightfield"],
)
def test_a_schedule_nested_too_deep_is_one_cli_line(deep_schedule, tmp_path, capsys, command):
    out = [] if command[0] == "design" else ["--out", str(tmp_path / "out")]
    assert main([*command, "--schedule", str(deep_schedule), *out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"--schedule {deep_schedule} is nested too deep" in err
    assert not (tmp_path / "out").exists()  # refused before any work
