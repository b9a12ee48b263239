"""``pacam validate-psf`` (rendered PSFs against Eqs. 12, 14, 18 on a grid) and ``pacam
validate-scene`` (a rendered scene against the per-surface convolution model, by region)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import check_positive
from ..experiments import scene_report
from ..experiments import validate_psf as validate
from ..experiments import validate_scene as vs
from ..exposure.spec import parse_crop
from ..model.design_file import resolve_design
from ..psf.scene import MODEL_MODES, QUANTUM_PX
from ..study.engine import check_workers, probe_scheduler
from .common import add_engine_args, add_outputs, add_preset
from .render_parts.optics_flags import add_camera_optics


def add(sub) -> None:
    p = sub.add_parser(
        "validate-psf", help="rendered PSFs against Eqs. 12, 14, 18 on a grid: CSV, PNG, Markdown"
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="18 points at 2^17 particles per window (about 1 min on 2 idle cores)",
    )
    p.add_argument(
        "--design",
        metavar="FILE",
        help="validate this camera (a design file, or a capture's or PSF's JSON) on a grid "
        "scaled to its depth and opening; default: the prototype",
    )
    add_engine_args(p)
    add_outputs(p)
    p.set_defaults(func=run_psf)
    _add_scene(sub)


def _add_scene(sub) -> None:

    p = sub.add_parser(
        "validate-scene",
        help="a rendered scene against the per-surface convolution model, by region",
    )
    p.add_argument(
        "scene",
        help="train, soccer, walker, family:NAME:SEED (e.g. family:occluders:12; see pacam "
        "scene generate), or a path to a Mitsuba .xml scene",
    )
    p.add_argument("--mode", default="coded", choices=MODEL_MODES)
    p.add_argument("--width", type=int, metavar="W", help="sensor px (default the preset's)")
    p.add_argument("--height", type=int, metavar="H", help="sensor px (default the preset's)")
    p.add_argument(
        "--crop",
        metavar="X,Y,W,H",
        help="the window (default: around the moving objects, padded by the PSF's reach)",
    )
    add_preset(p)
    p.add_argument("--spp", type=int, default=64, metavar="N", help="samples per pixel (64)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seeds S and S+1 (0)")
    p.add_argument(
        "--max-step-px", type=float, default=0.5, metavar="PX", help="motion per step (0.5)"
    )
    p.add_argument("--design", metavar="FILE", help="a camera design file instead of --preset")
    p.add_argument("--cover", type=float, metavar="PX_PER_MS", help="solve the design for it")
    p.add_argument("--f-number", type=float, metavar="N", help="with --cover: the opening")
    p.add_argument("--r-px", type=float, metavar="PX", help="with --cover: the defocus radius")
    p.add_argument("--depth", type=float, metavar="MM", help="the design's object depth")
    p.add_argument(
        "--speed",
        type=float,
        metavar="PX_PER_MS",
        help="scale the scene's motions so its fastest object moves this fast (preset px)",
    )
    p.add_argument(
        "--quantum",
        type=float,
        default=QUANTUM_PX,
        metavar="PX",
        help=f"the model's PSF quantum (default {QUANTUM_PX} px)",
    )
    p.add_argument("--quick", action="store_true", help="a small window at 16 spp (< 1 min)")
    add_camera_optics(p)  # the model follows: flat-fielded capture, diffracted model
    add_outputs(p)
    p.set_defaults(func=run_scene)


def run_psf(args: argparse.Namespace) -> int:

    if args.design is not None:
        grid = validate.grid_for(resolve_design(args.design), args.quick)
    else:
        grid = validate.QUICK if args.quick else validate.FULL
    workers = check_workers(args.workers, len(grid.depths_mm) * len(grid.f_numbers))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    s = validate.run(
        grid, args.out, args.force, not args.quiet, workers=workers, scheduler=args.scheduler
    )
    print(
        f"validate-psf ({grid.name}): {s['points']} points in {s['seconds']:.1f} s; r within "
        f"1 %: {s['r_pass']}/{s['r_points']} (max {s['r_max_err_pct']:.3f} %); a_i within 1 %: "
        f"{s['a_i_pass']}/{s['points']} (max {s['a_i_max_err_pct']:.3f} %); L1 at the noise "
        f"floor: {s['l1_pass']}/{s['points']} (L1/floor median {s['l1_ratio_median']:.2f}); "
        f"Eq. 14 vs {grid.base.n_patterns} patterns up to L1 {s['eq14_vs_discrete_max']:.3f}"
    )
    print(f"wrote {Path(args.out)}/: {', '.join(s['files'])}")
    return 0


def run_scene(args: argparse.Namespace) -> int:

    if args.speed is not None:
        check_positive("--speed", args.speed, "px/ms")
    check = vs.SceneCheck(
        scene=args.scene,
        mode=args.mode,
        width=args.width,
        height=args.height,
        crop=parse_crop(args.crop) if args.crop else None,
        spp=args.spp,
        seed=args.seed,
        max_step_px=args.max_step_px,
        preset=args.preset,
        design=args.design,
        cover_px_per_ms=args.cover,
        f_number=args.f_number,
        r_px=args.r_px,
        object_depth_mm=args.depth,
        speed_px_per_ms=args.speed,
        quantum_px=args.quantum,
        quick=args.quick,
        relative_illumination=args.relative_illumination,
        diffraction=args.diffraction,
    )
    s = vs.run(check, args.out, args.force, not args.quiet)
    print(f"validate-scene {args.scene}: {s['seconds']:.1f} s -> {Path(args.out)}/")
    for line in scene_report.findings(s["rows"], s["profile_width_px"]):
        print(line)
    return 0
