"""One mapping from parameter names to flags: library messages name parameters, and only the
CLI (``pacam_render.cli.common.FLAGS``) turns them into the flags a user typed."""

from __future__ import annotations

import argparse

import pytest

from pacam_render.cli import build_parser, main
from pacam_render.cli.common import FLAGS, user_words
from pacam_render.errors import ParameterError
from pacam_render.psf_render.spec import check_spp


def _all_flags(parser: argparse.ArgumentParser | None = None) -> set[str]:
    """Every flag of every command, and of their own subcommands (``pacam scene generate``)."""
    out: set[str] = set()
    for a in (parser or build_parser())._actions:
        if isinstance(a, argparse._SubParsersAction):
            for p in a.choices.values():
                out |= _all_flags(p)
        else:
            out.update(a.option_strings)
    return out


def test_every_mapped_flag_is_a_flag_of_some_command():
    assert set(FLAGS.values()) <= _all_flags()


@pytest.mark.parametrize(
    ("library", "cli"),
    [
        ("raise max_samples", "raise --max-samples"),
        (
            "`spp` must be an integer in [1, 16], got 0",
            "--spp must be an integer in [1, 16], got 0",
        ),
        ("pass `force=True` to overwrite it", "pass --force to overwrite it"),
        ("reduce `width`/`height` or `crop`", "reduce --width/--height or --crop"),
        ("noise_sigma (--noise-sigma) is 2", "noise_sigma (--noise-sigma) is 2"),  # named already
        (
            "64 spp at the seed of the crop, max_samples_x",
            "64 spp at the seed of the crop, max_samples_x",
        ),
    ],
)
def test_parameter_names_become_flags_and_prose_stays(library, cli):
    assert user_words(library) == cli


def test_a_library_check_names_the_parameter_and_the_cli_the_flag(tmp_path, capsys):
    with pytest.raises(ParameterError, match=r"^`spp` must be an integer"):
        check_spp(0)
    out = tmp_path / "psf"
    argv = ["psf", "--depth", "500", "--velocity", "0", "--render", "--spp", "0", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("pacam psf: error: --spp must be an integer in [1, ") and "`" not in err
    assert not out.exists()
