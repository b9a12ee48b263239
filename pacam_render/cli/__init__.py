"""The ``pacam`` command line. Bad input prints one clear line and exits 2, never a traceback.

One module per command, its parser (``add``) beside its run function (``run``); the flags they
share, the error handling and the mapping from library parameter names to flags are in
:mod:`.common`.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Sequence

from ..errors import FileKeyError, ParameterError
from ..exposure.integrate import CaptureInterrupted
from . import (
    dataset,
    deconvolve,
    demo,
    design,
    lightfield,
    optimize,
    psf,
    render,
    reproduce,
    scene,
    sensor,
    study,
    validate,
)
from .common import (
    check_common,
    interrupt_status,
    note_printer,
    terminate_as_interrupt,
    user_words,
)

COMMANDS = (
    design,
    psf,
    deconvolve,
    reproduce,
    render,
    lightfield,
    sensor,
    optimize,
    validate,
    study,
    scene,
    dataset,
    demo,
)
"""The command modules, in the order ``pacam --help`` lists them."""


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pacam`` with ``argv`` (default: ``sys.argv[1:]``); return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    name = f"pacam {args.command}"
    with warnings.catch_warnings(), terminate_as_interrupt():
        warnings.showwarning = note_printer(name)
        try:
            check_common(args)
            return args.func(args)
        except ParameterError as exc:  # a file's keys stay keys; a parameter becomes its flag
            words = str(exc) if isinstance(exc, FileKeyError) else user_words(str(exc))
            print(f"{name}: error: {words}", file=sys.stderr)
            return 2
        except CaptureInterrupted as exc:
            print(f"{name}: {exc}", file=sys.stderr)
            return interrupt_status(exc)
        except KeyboardInterrupt:
            print(f"{name}: interrupted", file=sys.stderr)
            return interrupt_status()
        except BrokenPipeError:  # e.g. `pacam design | head`: the reader left, nothing is wrong
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's final flush is quiet
            return 0
        except MemoryError as exc:  # past what the estimates foresaw: one line, not a traceback
            why = f": {exc}" if str(exc) else " (MemoryError); free memory, or ask for less"
            print(f"{name}: error: out of memory{why}", file=sys.stderr)
            return 1
        except OSError as exc:  # a disk full, a file gone: one line, not a traceback
            print(f"{name}: error: {exc}", file=sys.stderr)
            return 1


def build_parser() -> argparse.ArgumentParser:
    """The ``pacam`` parser, with every command's subparser."""
    parser = argparse.ArgumentParser(
        prog="pacam", description="Programmable-aperture motion-invariant camera simulator"
    )
    parser.add_argument("--version", action="version", version=f"pacam {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add(sub)
    return parser


def _version() -> str:
    from importlib.metadata import version

    return version("pacam_render")


if __name__ == "__main__":
    sys.exit(main())
