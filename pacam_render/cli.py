"""The ``pacam`` command line. Bad input prints one clear line and exits 2, never a traceback."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from .camera import PRESETS, CameraDesign, prototype
from .design import solve
from .errors import ParameterError, check_positive
from .report import design_report


def _design_from_args(args: argparse.Namespace) -> CameraDesign:
    for flag, unit in (("depth", "mm"), ("exposure", "ms"), ("max_velocity", "px/ms")):
        if getattr(args, flag) is not None:
            check_positive("--" + flag.replace("_", "-"), getattr(args, flag), unit)
    if args.preset not in PRESETS:
        raise ParameterError(f"unknown preset {args.preset!r}; valid: {', '.join(PRESETS)}")
    base = prototype() if args.depth is None else prototype(object_depth_mm=args.depth)
    if args.max_velocity is None:
        if args.f_number is not None or args.r_px is not None:
            raise ParameterError("--f-number and --r-px need --max-velocity (the speed to cover)")
        if args.exposure is not None:
            base = base.with_(exposure_ms=args.exposure)
        return base
    return solve(
        args.max_velocity,
        exposure_ms=args.exposure,
        object_depth_mm=args.depth,
        f_number=args.f_number,
        r_px=args.r_px,
        base=base,
    )


def _cmd_design(args: argparse.Namespace) -> int:
    d = _design_from_args(args)
    if args.json:
        print(json.dumps(d.summary(), indent=2))
    else:
        print(design_report(d))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    print(design_report(prototype()))
    return 0


def _add_design_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="prototype", help="base camera (default: prototype)")
    p.add_argument("--depth", type=float, metavar="MM", help="object depth Z, mm (default 500)")
    p.add_argument("--exposure", type=float, metavar="MS", help="exposure 2T, ms (default 45)")
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
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pacam", description="Programmable-aperture motion-invariant camera simulator"
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("design", help="derive the camera's optics, schedule, r and a_i")
    _add_design_args(p)
    p.set_defaults(func=_cmd_design)
    p = sub.add_parser("demo", help="the main job on built-in defaults")
    p.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ParameterError as exc:
        print(f"pacam {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
