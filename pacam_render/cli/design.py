"""``pacam design``: report on a camera design, solve one for a speed, and write it to a file
that every command takes (``--design FILE``)."""

from __future__ import annotations

import argparse
import json

from ..errors import ParameterError, check_positive
from ..model.camera import CameraDesign, preset
from ..model.design import note_far_design, solve
from ..model.design_file import resolve_design, write_design
from ..model.masks import read_mask_stack
from ..model.report import design_report
from ..model.schedule_file import apply_schedule, read_schedule
from .common import add_force, add_preset


def add(sub) -> None:
    p = sub.add_parser(
        "design", help="derive a camera's optics, schedule, r and a_i; write a design file"
    )
    add_preset(p)
    p.add_argument(
        "--design",
        metavar="FILE",
        help="start from a design file, or a capture's or PSF's JSON (default: --preset)",
    )
    p.add_argument("--depth", type=float, metavar="MM", help="object depth Z, mm (default 500)")
    p.add_argument("--exposure", type=float, metavar="MS", help="exposure 2T, ms (default 45)")
    p.add_argument("--n-patterns", type=int, metavar="N", help="patterns per exposure (16)")
    p.add_argument(
        "--lcos-rate", type=float, metavar="FPS", help="patterns the LCoS shows per second (365)"
    )
    p.add_argument(
        "--max-velocity",
        type=float,
        metavar="PX_PER_MS",
        help="fastest object speed to keep motion-invariant; solves for R, focus, r and a_i",
    )
    p.add_argument(
        "--f-number", type=float, metavar="N", help="fix the opening (with --max-velocity)"
    )
    p.add_argument(
        "--r-px", type=float, metavar="PX", help="fix the defocus radius (with --max-velocity)"
    )
    p.add_argument(
        "--schedule", metavar="SCHEDULE.json", help="show pacam optimize's centres (legacy file)"
    )
    p.add_argument(
        "--masks",
        metavar="PATH",
        help="a bitmap schedule: a .npy (N, H, W) stack or a folder of LCoS images, one per "
        "pattern in name order (e.g. pacam optimize's lcos/)",
    )
    p.add_argument("--sensor", metavar="PRESET", help="the image sensor's noise preset to record")
    p.add_argument("--write", metavar="FILE.toml", help="write the design file (and its masks)")
    add_force(p, "overwrite an existing design file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    d = _design_from_args(args)
    if args.write is not None:
        written = write_design(args.write, d, args.force)
        print(f"wrote {', '.join(map(str, written))} (design digest {d.digest()})")
    if args.json:
        print(json.dumps(d.summary(), indent=2))
    elif args.write is None:
        print(design_report(d))
    return 0


def _base(args: argparse.Namespace) -> CameraDesign:
    """The starting design, with the flags that change it without solving."""
    if args.design is not None and args.preset != "prototype":
        raise ParameterError("give --design or --preset, not both: each is the camera")
    depth = {} if args.depth is None else {"object_depth_mm": args.depth}
    if args.design is not None:
        base = resolve_design(args.design, **depth)
    else:
        base = preset(args.preset, **depth)
    changes = {
        "lcos_rate_fps": args.lcos_rate,
        "n_patterns": args.n_patterns,
        "sensor_preset": args.sensor,
    }
    if args.max_velocity is None:
        changes["exposure_ms"] = args.exposure
    changed = {k: v for k, v in changes.items() if v is not None and v != getattr(base, k)}
    base = base.with_(**changed)
    if changed:  # a changed design is not the one it started from: its name says what changed
        base = base.with_(name=f"{base.name}, {_changes_named(base, changed)}")
    return _schedule(args, base)


def _changes_named(d: CameraDesign, changed: dict) -> str:
    """What the flags changed, in words: "32 patterns in 20 ms", "LCoS at 2000 patterns/s"."""
    words = []
    if {"n_patterns", "exposure_ms"} & set(changed):  # the two only mean something together
        words.append(f"{d.n_patterns} patterns in {d.exposure_ms:g} ms")
    if "lcos_rate_fps" in changed:
        words.append(f"LCoS at {d.lcos_rate_fps:g} patterns/s")
    if "sensor_preset" in changed:
        words.append(f"sensor {d.sensor_preset}")
    return ", ".join(words)


def _schedule(args: argparse.Namespace, base: CameraDesign) -> CameraDesign:
    if args.schedule is not None and args.masks is not None:
        raise ParameterError("give --schedule or --masks, not both: each is the schedule")
    if args.schedule is not None:
        return apply_schedule(base, read_schedule(args.schedule), args.schedule)
    if args.masks is None:
        return base

    stack = read_mask_stack(args.masks, base.lcos_pitch_mm, args.masks, "`masks`")
    return base.with_(
        pattern_centres_mm=None,
        pattern_masks=stack,
        n_patterns=stack.n_patterns,
        R_mm=stack.equivalent_radius_mm(),
        name=f"bitmap schedule ({args.masks})",
        quoted_a_i_px_per_ms2=None,
    )


def _design_from_args(args: argparse.Namespace) -> CameraDesign:
    for flag, unit in (
        ("depth", "mm"),
        ("exposure", "ms"),
        ("max_velocity", "px/ms"),
        ("lcos_rate", "patterns/s"),
    ):
        if getattr(args, flag) is not None:
            check_positive("--" + flag.replace("_", "-"), getattr(args, flag), unit)
    base = _base(args)
    if args.max_velocity is None:
        if args.f_number is not None or args.r_px is not None:
            raise ParameterError("--f-number and --r-px need --max-velocity (the speed to cover)")
        base.check_lcos_rate()
        note_far_design(base)  # a design file's too (the solver notes its own)
        return base
    if base.designed:
        raise ParameterError(
            "--max-velocity solves the parabola's opening and focus; a --schedule or --masks "
            "design is already fixed: leave one out"
        )
    d = solve(
        args.max_velocity,
        exposure_ms=args.exposure,
        object_depth_mm=args.depth,
        f_number=args.f_number,
        r_px=args.r_px,
        base=base,
    )
    d.check_lcos_rate()
    return d
