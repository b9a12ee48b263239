"""What the commands share: the common flags, written once, and the one place where a library
message's parameter names become the flags a user typed.

Library messages name parameters (:mod:`pacam_render.errors`): a name with an underscore bare
(``max_step_px``), a one-word name in backticks (``"`spp`"``), so that "64 spp" stays prose.
:func:`user_words` maps both through :data:`FLAGS`; ``"`force=True`"`` becomes ``--force``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import sys
import warnings
from pathlib import Path

from ..errors import ParameterError
from ..io.outputs import writable_dir
from ..limits import DEFAULT_MAX_SAMPLES, DEFAULT_MAX_STEPS, PacamWarning
from ..render.variant import choose_variant

FLAGS = {
    "max_step_px": "--max-step-px",
    "max_steps": "--max-steps",
    "max_samples": "--max-samples",
    "noise_ratio": "--noise-ratio",
    "budget_hours": "--budget",
    "workers": "--workers",
    "scheduler": "--scheduler",
    "noise_target": "--noise-target",
    "cover_px_per_ms": "--cover",
    "cover": "--cover",
    "schedule": "--schedule",
    "design": "--design",
    "max_velocity_px_per_ms": "--max-velocity",
    "object_depth_mm": "--depth",
    "depth_range_mm": "--depth-range",
    "exposure_ms": "--exposure",
    "f_number": "--f-number",
    "r_px": "--r-px",
    "allow_psf_mismatch": "--allow-psf-mismatch",
    "lcos_rate_fps": "--lcos-rate",
    "n_patterns": "--n-patterns",
    "light_level": "--light-level",
    "noise_sigma": "--noise-sigma",
    "quantum_px": "--quantum",
    "per_pattern": "--per-pattern",
    "relative_illumination": "--relative-illumination",
    "diffraction": "--diffraction",
    "lcos_contrast": "--lcos-contrast",
    "lcos_fill_factor": "--lcos-fill-factor",
    "lcos_switching_ms": "--lcos-switching",
    "velocity_px_per_ms": "--velocity",
    "velocity": "--velocity",
    "spp": "--spp",
    "passes": "--passes",
    "seed": "--seed",
    "size": "--size",
    "film": "--film",
    "crop": "--crop",
    "width": "--width",
    "height": "--height",
    "mode": "--mode",
    "preset": "--preset",
    "sensor": "--sensor",
    "psf": "--psf",
    "like": "--like",
    "render": "--render",
    "method": "--method",
    "colour": "--colour",
    "layer": "--layer",
    "starts": "--starts",
    "iterations": "--iterations",
    "quick": "--quick",
    "out": "--out",
    "force": "--force",
    "grey": "--grey",
    "margin_px": "--margin-px",
    "max_disk": "--max-disk-gib",
    "alpha": "--uniform-share",
    "masks": "--masks",
    "positions": "--positions",
    "sweeps": "--sweeps",
    "noise_draws": "--noise-draws",
    "check_seeds": "--check-seeds",
    "family": "--family",
    "speed_range_px_per_ms": "--speed-range",
    "object_count": "--objects",
    "size_range_px": "--size-range",
    "direction_spread_deg": "--direction-spread",
    "wall_depth_mm": "--wall-depth",
    "textures": "--textures",
    "window": "--window",
    "cells": "--cells",
    "levels": "--levels",
    "light": "--light",
    "objective": "--objective",
    "still_weight": "--still-weight",
    "aggregate": "--aggregate",
    "focus_mm": "--focus",
    "held_out": "--held-out",
    "max_still_loss_db": "--max-still-loss",
    "held_passes": "--held-passes",
    "space": "--space",
}
"""Parameter names in library messages, and the flags a CLI user typed instead: the one
mapping (a file's keys, :class:`~pacam_render.errors.FileKeyError`, are left as they are)."""
_QUOTED = re.compile(r"`(" + "|".join(map(re.escape, FLAGS)) + r")(?:=True)?`")
_BARE = re.compile(  # a key after its "[table] " is a file's key, not a flag
    r"(?<![\w-])(?<!\] )(" + "|".join(n for n in FLAGS if "_" in n) + r")(?![\w-])(?! \(--)"
)


def user_words(message: str) -> str:
    """A library message in the CLI's words: parameter names become their flags.

    >>> user_words("raise max_samples, or lower `spp` (64 spp now); pass `force=True`")
    'raise --max-samples, or lower --spp (64 spp now); pass --force'
    >>> user_words("over budget_hours; raise [render] noise_ratio in the file")
    'over --budget; raise [render] noise_ratio in the file'
    """
    message = _QUOTED.sub(lambda m: FLAGS[m.group(1)], message)
    return _BARE.sub(lambda m: FLAGS[m.group(1)], message)


def add_out(p: argparse.ArgumentParser, help: str | None = None, **kw) -> None:
    """``--out DIR`` (required unless ``default`` is given)."""
    p.add_argument("--out", required="default" not in kw, metavar="DIR", help=help, **kw)


def add_force(p: argparse.ArgumentParser, help: str = "overwrite results in DIR") -> None:
    p.add_argument("--force", action="store_true", help=help)


def add_quiet(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def add_preset(p: argparse.ArgumentParser, help: str | None = "base camera (default: prototype)"):
    p.add_argument("--preset", default="prototype", help=help)


def add_design_flags(p: argparse.ArgumentParser) -> None:
    """The camera: ``--preset`` or ``--design FILE``, and a covering design or a schedule."""
    add_preset(p)
    p.add_argument(
        "--design",
        metavar="FILE",
        help="a camera design file (pacam design --write), or a capture/psf JSON whose design "
        "to reuse; replaces --preset",
    )
    p.add_argument(
        "--cover",
        type=float,
        metavar="PX_PER_MS",
        help="solve the design so this speed (the design's full-sensor px) is motion-invariant",
    )
    p.add_argument(
        "--f-number", type=float, metavar="N", help="with --cover: keep this opening (F-number)"
    )
    p.add_argument(
        "--r-px", type=float, metavar="PX", help="with --cover: keep this defocus radius r, px"
    )
    p.add_argument(
        "--schedule",
        metavar="SCHEDULE.json",
        help="show a designed schedule (a legacy pacam optimize schedule.json)",
    )


def design_spec_fields(args: argparse.Namespace) -> dict:
    """The CaptureSpec fields that :func:`add_design_flags` sets."""
    if args.design is not None and args.preset != "prototype":
        raise ParameterError("give --design or --preset, not both: each is the camera")
    return {
        "preset": args.preset,
        "design": args.design,
        "cover_px_per_ms": args.cover,
        "f_number": args.f_number,
        "r_px": args.r_px,
        "schedule": args.schedule,
    }


def add_seed_and_steps(p: argparse.ArgumentParser) -> None:
    """``--seed`` and ``--max-step-px``: a render's random numbers and its time steps."""
    p.add_argument("--seed", type=int, default=0, metavar="S")
    p.add_argument(
        "--max-step-px",
        type=float,
        default=0.5,
        metavar="PX",
        help="largest image motion between time steps (default 0.5 px)",
    )


def add_grey(p: argparse.ArgumentParser, what: str = "captures") -> None:
    """``--grey``: render one channel with Mitsuba's mono variant (no RGB)."""
    p.add_argument(
        "--grey",
        action="store_true",
        help=f"grey {what}: one channel (luminance) rendered with Mitsuba's mono variant "
        "(llvm_ad_mono); the same as PACAM_VARIANT=llvm_ad_mono, and refused with an RGB one",
    )


def add_outputs(p: argparse.ArgumentParser, force_help: str = "overwrite results in DIR") -> None:
    """``--out DIR``, ``--force`` and ``--quiet``, in that order."""
    add_out(p)
    add_force(p, force_help)
    add_quiet(p)


def add_engine_args(p: argparse.ArgumentParser) -> None:
    """Where the command's independent tasks run (:mod:`pacam_render.study.engine`)."""
    p.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes of a local Dask cluster (default: one per core, at most one per "
        "task; 0: serially, in this process)",
    )
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on an existing Dask cluster (tcp://host:8786)"
    )


def add_limit_args(p: argparse.ArgumentParser) -> None:
    """Bounds on a capture's work, and how often it saves its finished steps."""
    p.add_argument(
        "--max-steps",
        type=int,
        default=DEFAULT_MAX_STEPS,
        metavar="N",
        help=f"refuse a capture of more time steps (default {DEFAULT_MAX_STEPS})",
    )
    p.add_argument(
        "--max-samples",
        type=int,
        default=DEFAULT_MAX_SAMPLES,
        metavar="N",
        help="refuse more than N = spp x width x height samples, counted as rendered (the "
        "passes rounded up to whole time steps; a noise target's pilot; a target the pilot "
        f"puts beyond N is refused after it) (default 2^35 = {DEFAULT_MAX_SAMPLES}, about 1.5 h "
        "on 2 cores)",
    )
    p.add_argument(
        "--checkpoint-every",
        type=float,
        default=5.0,
        metavar="S",
        help="seconds between saves of the finished steps to DIR/.partial (default 5)",
    )


def check_common(args: argparse.Namespace) -> None:
    """Flags that several commands share, refused before any work: a size of 0 px would
    quietly become the default (``args.width or ...``), an empty --out the current folder,
    and, for the commands that render on local Dask workers, a ``PACAM_VARIANT`` that
    cannot render here (:func:`~pacam_render.render.variant.choose_variant`)."""
    for flag in ("width", "height"):
        value = getattr(args, flag, None)
        if value is not None and value < 1:
            raise ParameterError(f"--{flag} must be a positive number of px, got {value}")
    out = getattr(args, "out", None)
    if out is not None and not str(out).strip():
        raise ParameterError(f"--out must name a folder or file, got {out!r}")
    if (
        os.environ.get("PACAM_VARIANT", "").strip()
        and hasattr(args, "workers")
        and getattr(args, "scheduler", None) is None
    ):  # a sweep renders in local workers: refuse a variant that cannot render here once,
        # before they start, not once per point (a --scheduler's machines may differ)
        choose_variant()


def note_printer(name: str):
    """``warnings.showwarning`` that prints a :class:`PacamWarning` as one ``note:`` line."""
    default = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PacamWarning):
            print(f"{name}: note: {user_words(str(message))}", file=sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    return show


_SIGNALLED: list[int] = []
"""The signal that interrupted this command, if one did (SIGTERM)."""


@contextlib.contextmanager
def terminate_as_interrupt():
    """SIGTERM is handled as Ctrl-C (KeyboardInterrupt), so both save alike; the exit status
    still says which (:func:`interrupt_status`)."""

    def handler(signum, frame):
        _SIGNALLED.append(signum)
        raise KeyboardInterrupt

    _SIGNALLED.clear()
    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def interrupt_status(exc: BaseException | None = None) -> int:
    """The exit status of an interrupted command, by the shell's convention 128 + signal:
    143 after SIGTERM, 130 after Ctrl-C (SIGINT). A capture that caught the signal itself
    says which (``exc.signum``)."""
    signum = getattr(exc, "signum", None) or (_SIGNALLED[-1] if _SIGNALLED else signal.SIGINT)
    return 128 + int(signum)


@contextlib.contextmanager
def new_folder(out: Path):
    """Create ``out`` (proven writable); if the command fails and leaves it empty, remove it."""
    created = not out.exists()
    writable_dir(out)
    try:
        yield out
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise
