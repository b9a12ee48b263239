"""``pacam demo``: the main job on built-in defaults (the train set, coded, deblurred)."""

from __future__ import annotations

import argparse

from ..experiments.demo import DEMO_SPP, check_size, run_demo
from ..io.lock import output_lock
from ..io.outputs import prepare_out_dir
from ..model.camera import prototype
from ..model.report import design_report
from .common import add_force, add_out


def add(sub) -> None:

    p = sub.add_parser("demo", help="the main job on built-in defaults")
    add_out(p, default="demo_out", help="default demo_out/")
    p.add_argument(
        "--width",
        type=int,
        help="render the whole frame of a binned sensor this wide instead of a window of the "
        "full 1280x960 one (the default: the camera at its real pixel scale)",
    )
    p.add_argument("--height", type=int, help="with --width: the binned sensor's height")
    p.add_argument("--spp", type=int, default=DEMO_SPP, help=f"default {DEMO_SPP}")
    add_force(p, "overwrite a previous demo in DIR")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    check_size(args.width, args.height, args.spp)
    out = prepare_out_dir(args.out, args.force)
    print(design_report(prototype()))
    where = (
        "a window of the full 1280x960 sensor"
        if args.width is None and args.height is None
        else f"a binned {args.width or 1280}x{args.height or 960} sensor"
    )
    print(f"\nrendering the train set ({where}, {args.spp} spp) ...")
    with output_lock(out):
        fig = run_demo(out, args.width, args.height, args.spp, args.force)
    print((fig.parent / "demo.md").read_text())
    print(f"figure: {fig}")
    return 0
