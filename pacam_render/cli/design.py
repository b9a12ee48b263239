"""``pacam design``: the camera's optics, schedule, r and a_i, or a design solved for a speed."""

from __future__ import annotations

import argparse
import json

from ..errors import ParameterError, check_positive
from ..model.camera import CameraDesign, preset
from ..model.design import solve
from ..model.report import design_report
from .common import add_preset


def add(sub) -> None:
    p = sub.add_parser("design", help="derive the camera's optics, schedule, r and a_i")
    add_preset(p)
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
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    d = _design_from_args(args)
    if args.json:
        print(json.dumps(d.summary(), indent=2))
    else:
        print(design_report(d))
    return 0


def _design_from_args(args: argparse.Namespace) -> CameraDesign:
    for flag, unit in (("depth", "mm"), ("exposure", "ms"), ("max_velocity", "px/ms")):
        if getattr(args, flag) is not None:
            check_positive("--" + flag.replace("_", "-"), getattr(args, flag), unit)
    depth = {} if args.depth is None else {"object_depth_mm": args.depth}
    base = preset(args.preset, **depth)
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
