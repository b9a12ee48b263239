"""``pacam optimize``: design the aperture schedule for a speed and depth range."""

from __future__ import annotations

import argparse

from ..errors import ParameterError
from ..io.outputs import prepare_out_dir
from ..model.camera import preset
from .common import add_outputs, add_preset, new_folder


def add(sub) -> None:
    p = sub.add_parser("optimize", help="design the aperture schedule for a speed/depth range")
    p.add_argument(
        "--max-velocity",
        type=float,
        required=True,
        metavar="PX_PER_MS",
        help="cover speeds |s| <= this, px/ms of the preset's sensor",
    )
    p.add_argument("--depth-range", metavar="NEAR,FAR", help="mm (default: the preset's depth)")
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help="photons/px/ms of white through the full lens (default 300, the demo's)",
    )
    p.add_argument(
        "--sensor",
        default="grasshopper-icx285",
        help="sensor noise preset (default grasshopper-icx285; paper: sigma 0.01)",
    )
    p.add_argument("--n-patterns", type=int, default=16, metavar="N", help="default 16")
    p.add_argument(
        "--free-radius",
        action="store_true",
        help="also choose the opening's radius (light counted through the noise)",
    )
    p.add_argument("--f-number", type=float, metavar="N", help="the parabola's opening")
    p.add_argument("--r-px", type=float, metavar="PX", help="the parabola's defocus radius")
    add_preset(p)
    p.add_argument(
        "--design",
        metavar="FILE",
        help="design the schedule for this camera (a design file) instead of --preset",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random starts (default 0)")
    p.add_argument("--starts", type=int, metavar="K", help="local searches (default 6; quick 2)")
    p.add_argument(
        "--iterations",
        type=int,
        metavar="I",
        help="L-BFGS-B iterations per start (default 100; quick 30)",
    )
    p.add_argument("--quick", action="store_true", help="a coarse grid, 2 short starts")
    add_outputs(p)
    p.set_defaults(func=run)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from ..io.lock import output_lock
    from ..optimize.run import run_optimize
    from ..optimize.search import Problem, check_problem, reference_design

    problem = Problem(
        max_velocity_px_per_ms=args.max_velocity,
        depth_range_mm=_depth_range(args.depth_range, args.preset, args.design),
        n_patterns=args.n_patterns,
        sensor=args.sensor,
        light_level=args.light_level,
        preset=args.preset,
        f_number=args.f_number,
        r_px=args.r_px,
        free_radius=args.free_radius,
        design=args.design,
    )
    check_problem(problem)
    reference_design(problem)  # the parabola must cover the range: refused before any output
    for flag in ("starts", "iterations"):
        v = getattr(args, flag)
        if v is not None and (v < 1):
            raise ParameterError(f"--{flag} must be an integer >= 1, got {v!r}")
    if not 0 <= args.seed < 2**32:
        raise ParameterError(f"--seed must be an integer in [0, 2^32), got {args.seed!r}")
    out = prepare_out_dir(args.out, args.force)
    with new_folder(out), output_lock(out):  # an interrupt before any file leaves no folder
        doc = run_optimize(problem, out, quick=args.quick, seed=args.seed, force=args.force,
                           starts=args.starts, iterations=args.iterations,
                           progress=not args.quiet)  # fmt: skip
    print((out / "report.md").read_text())
    gain = doc["objective_worst"] - doc["parabola_objective_worst"]
    print(f"worst-case gain over the parabola at equal light: {gain:+.2f} dB (predicted)")
    print(
        f"written: {out / 'design.toml'} (pacam render/psf/validate-psf --design), "
        f"schedule.json, report.md, 4 plots, lcos/ ({doc['n_patterns']} PNG)"
    )
    return 0


def _depth_range(text: str | None, preset_name: str, design: str | None) -> tuple[float, float]:
    if text is None:
        if design is not None:
            from ..model.design_file import resolve_design

            d = resolve_design(design).object_depth_mm
        else:
            d = preset(preset_name).object_depth_mm
        return d, d
    try:
        near, far = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError(f"--depth-range must be NEAR,FAR in mm, got {text!r}") from None
    return near, far
