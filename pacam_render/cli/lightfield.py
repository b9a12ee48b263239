"""``pacam lightfield``: render a scene's window once through the whole lens, into a store that
``pacam render --from`` synthesises any design's capture from."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from ..errors import ParameterError, check_positive
from ..exposure.spec import CaptureSpec, parse_crop
from ..lightfield import StoreSpec, render_lightfield, synthesize
from ..lightfield.proposal import DEFENSIVE
from ..lightfield.synthesis import store_noise_note
from ..lightfield.target import PILOT_SPP
from ..limits import PacamWarning, gib, note
from .common import add_design_flags, add_grey, add_quiet, add_seed_and_steps, design_spec_fields
from .render import noise_target_from_flags

DEFAULT_STORE_SPP = 64
"""Samples per pixel and pass of a store without a noise target."""


def add(sub) -> None:
    p = sub.add_parser(
        "lightfield",
        help="render a light-field store: one render that serves every design's capture",
    )
    p.add_argument(
        "scene",
        help="train, soccer, walker, family:NAME:SEED (e.g. family:occluders:12; see pacam "
        "scene generate), or a path to a Mitsuba .xml scene",
    )
    p.add_argument("--width", type=int, default=1280, metavar="W", help="sensor px (default 1280)")
    p.add_argument("--height", type=int, default=960, metavar="H", help="sensor px (default 960)")
    p.add_argument("--crop", metavar="X,Y,W,H", help="the window of the sensor to store")
    add_design_flags(p)
    p.add_argument("--depth", type=float, metavar="MM", help="the design's object depth")
    p.add_argument(
        "--spp",
        type=int,
        metavar="N",
        help=f"samples per pixel and pass, shared among a moving scene's time steps (default "
        f"{DEFAULT_STORE_SPP}, or what a noise target plans)",
    )
    _add_noise_target(p)
    p.add_argument(
        "--passes",
        type=int,
        default=4,
        metavar="P",
        help="independent passes: their spread is every synthesised capture's Monte "
        "Carlo error (default 4)",
    )
    add_seed_and_steps(p)
    p.add_argument(
        "--designs",
        nargs="*",
        default=[],
        metavar="FILE",
        help="design files the store's lens samples focus on (default: this design "
        "in its coded and normal modes); others are served too, less efficiently",
    )
    p.add_argument(
        "--margin-px",
        type=int,
        metavar="PX",
        help="extra film on every side, for designs focused elsewhere (default: what "
        "the designs need)",
    )
    p.add_argument(
        "--uniform-share",
        type=float,
        default=DEFENSIVE,
        metavar="ALPHA",
        help=f"the share of lens samples spread uniformly over the whole lens (default "
        f"{DEFENSIVE:g}); 1 for a store that `pacam optimize --lightfield` searches, where "
        "any opening may be tried",
    )
    p.add_argument(
        "--max-disk-gib",
        type=float,
        default=20.0,
        metavar="GIB",
        help="refuse a store larger than this on disk (default 20)",
    )
    p.add_argument("--no-truth", action="store_true", help="leave out the ground-truth layers")
    add_grey(p, "the store")
    p.add_argument("--out", required=True, metavar="STORE", help="the store's folder")
    add_quiet(p)
    p.set_defaults(func=run)


def _add_noise_target(p) -> None:
    """``--noise-ratio`` (with ``--sensor`` and ``--light-level``) or ``--noise-target``."""
    p.add_argument(
        "--noise-ratio",
        type=float,
        metavar="R",
        help="plan the samples so that every design the store is for (--designs) has a Monte "
        "Carlo sigma of at most R x the sensor's noise (--sensor), from a pilot store",
    )
    p.add_argument(
        "--noise-target",
        type=float,
        metavar="SIGMA",
        help="as --noise-ratio, to this Monte Carlo sigma (the captures' units)",
    )
    p.add_argument("--sensor", metavar="PRESET", help="the sensor whose noise --noise-ratio scales")
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help="with --sensor: photons/px/ms of white through the full lens (default the preset's)",
    )


def _spec(args: argparse.Namespace):

    crop = parse_crop(args.crop) if args.crop else None
    base = dict(
        scene=args.scene,
        width=args.width,
        height=args.height,
        crop=crop,
        grey=bool(args.grey),
        object_depth_mm=args.depth,
    )
    capture = CaptureSpec.geometric(  # a store is geometric (lightfield/render.py)
        **base,
        **design_spec_fields(args),
        spp=DEFAULT_STORE_SPP if args.spp is None else args.spp,
        passes=args.passes,
        seed=args.seed,
        max_step_px=args.max_step_px,
    )
    designs = tuple(CaptureSpec.geometric(**base, design=d) for d in args.designs)
    return StoreSpec(capture, margin_px=args.margin_px, designs=designs, alpha=args.uniform_share)


def run(args: argparse.Namespace) -> int:

    check_positive("--max-disk-gib", args.max_disk_gib, "GiB")
    if args.passes < 2:
        raise ParameterError(
            f"--passes must be >= 2 (their spread is the error), got {args.passes}"
        )
    target = noise_target_from_flags(args)
    spec = _spec(args)
    store = render_lightfield(
        spec,
        Path(args.out),
        progress=not args.quiet,
        max_disk=int(args.max_disk_gib * 2**30),
        truth=not args.no_truth,
        target=target,
    )
    m = store.manifest
    if "noise_target" in m.raw:
        plan = m.raw["noise_target"]
        worst = max(plan["designs"], key=lambda r: r["spp_needed"])
        name = worst["mode"] + (f" {worst['design']}" if worst["design"] else "")
        print(
            f"noise target: {plan['spp']} spp per pass, set by {name} (pilot sigma "
            f"{worst['pilot_sigma']:.3g} at {PILOT_SPP} spp, target {worst['target_sigma']:.3g})"
        )
    size = sum(f.stat().st_size for f in Path(args.out).glob("*.npz"))
    steps, cam = len(m.steps[0]), m.camera
    print(
        f"light-field store of {m.scene}: window {list(cam.window)} (+{cam.margin_px} px "
        f"margin), {m.passes} passes of {steps} step(s), {m.seconds:.1f} s of tracing, "
        f"{gib(size)} -> {args.out}"
    )
    print(
        f"digest {store.digest}; synthesise a design's capture with: pacam render "
        f"{m.scene} --from {args.out} ..."
    )
    if target is None:  # a target sized the store already; else say what its samples give
        with warnings.catch_warnings():  # the capture's own notes are not the store's
            warnings.simplefilter("ignore", PacamWarning)
            cap = synthesize(store, spec.capture, progress=False)
            noisy = store_noise_note(cap, spp_name="--spp")
        if noisy:
            note(f"{noisy} (the coded capture it was rendered for)")
    return 0
