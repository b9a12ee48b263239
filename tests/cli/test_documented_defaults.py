"""What the docs and ``--help`` say about the commands' defaults is what the code does
(issue 35: the README once said every command's light level defaulted to 7000; issue 38 moved
those sentences from the README to the docs pages read here)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from pacam_render.cli import build_parser
from pacam_render.optimize import search
from pacam_render.sensor.apply import _light_level
from pacam_render.sensor.model import SensorModel
from pacam_render.sensor.radiometry import DEFAULT_LIGHT_LEVEL
from pacam_render.study.spec import AXES

DOCS = Path(__file__).resolve().parents[2] / "docs"
SENSOR_PAGE = DOCS / "concepts" / "sensor.md"
VALIDATE_PSF_PAGE = DOCS / "validation" / "validate_psf.md"


def _help(command: str, flag: str) -> str:
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    action = next(a for a in sub.choices[command]._actions if flag in a.option_strings)
    return action.help


def _help_default(command: str) -> float:
    found = re.search(r"default (\d+(?:\.\d+)?)", _help(command, "--light-level"))
    assert found, f"pacam {command} --light-level's help names no default"
    return float(found.group(1))


def test_the_light_level_defaults_in_help_and_readme_are_the_codes():
    # what each command does without --light-level
    physical = SensorModel.from_preset("grasshopper-icx285")
    code = {
        "render": _light_level(physical, None),  # render --sensor and sensor both end here
        "sensor": _light_level(physical, None),
        "study": AXES["light_level"],
        "optimize": search.DEFAULT_LIGHT_LEVEL,
    }
    assert code["render"] == DEFAULT_LIGHT_LEVEL
    for command in ("render", "sensor", "optimize"):
        assert _help_default(command) == code[command], command
    text = " ".join(SENSOR_PAGE.read_text().split())
    said = re.search(
        r"its default is (\d+) for `render`, `sensor` and `study` \(a point without "
        r"`light_level`\), and (\d+) for `optimize`",
        text,
    )
    assert said, "docs/concepts/sensor.md's sentence on the --light-level defaults is gone"
    assert float(said.group(1)) == code["render"] == code["sensor"] == code["study"]
    assert float(said.group(2)) == code["optimize"]


def test_validate_psf_quick_is_described_as_it_is():
    """``--quick``'s help and the docs give its grid and a measured time, not ~30 s."""
    from pacam_render.experiments.validate_psf import QUICK

    help_text = _help("validate-psf", "--quick")
    particles = QUICK.particles_per_window.bit_length() - 1
    assert 1 << particles == QUICK.particles_per_window
    assert f"{QUICK.n_points} points at 2^{particles} particles per window" in help_text
    assert "30 s" not in help_text
    text = " ".join(VALIDATE_PSF_PAGE.read_text().split())
    assert f"`--quick` has {QUICK.n_points} points and takes about a minute on 2 cores" in text
