"""``pacam study``: a rendered sweep (capture, sensor, deconvolution, scores) on Dask."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import check_positive
from ..exposure.integrate import CaptureInterrupted
from ..limits import duration
from ..study import load_study, run_study
from ..study.engine import check_scheduler, check_workers, probe_scheduler
from ..study.results import RESULTS, read_csv
from .common import (
    add_engine_args,
    add_force,
    add_grey,
    add_out,
    add_quiet,
    interrupt_status,
)


def add(sub) -> None:
    p = sub.add_parser(
        "study", help="a rendered sweep (capture, sensor, deconvolution, scores) on Dask"
    )
    p.add_argument("spec", metavar="SPEC", help="a study TOML file, or crossover or speed")
    add_out(p, help="results.csv, report.md, plots")
    p.add_argument("--quick", action="store_true", help="the study's small version")
    add_engine_args(p)
    p.add_argument("--keep-images", action="store_true", help="keep each point's EXR layers")
    p.add_argument(
        "--budget",
        type=float,
        metavar="HOURS",
        help="refuse the study if its renders, predicted from pilot passes, take longer",
    )
    add_grey(p, "captures (grey = true in [render]); colour sensor presets become their mono twins")
    add_force(p, "start afresh over other results")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    check_scheduler(args.scheduler)
    # every key checked before any work
    spec = load_study(args.spec, quick=args.quick, grey=args.grey)
    workers = check_workers(args.workers, len(spec.groups()))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    where = args.scheduler or (f"{workers} local workers" if workers else "serially, in-process")
    groups = len(spec.groups())
    grey = ", grey (one channel, mono variant)" if spec.render.get("grey") else ""
    print(f"study {spec.name}: {len(spec.points)} points in {groups} renders, {where}{grey}")
    if args.budget is not None:
        check_positive("--budget", args.budget, "h")

    def estimate(summary) -> None:
        print(
            f"study {spec.name}: the renders still to do need about "
            f"{duration(summary.estimate_s)} (predicted from their pilot passes, kept)",
            flush=True,
        )

    try:
        s = run_study(
            spec,
            args.out,
            workers,
            args.scheduler,
            args.keep_images,
            args.force,
            not args.quiet,
            budget_hours=args.budget,
            on_estimate=estimate,
        )
    except (KeyboardInterrupt, CaptureInterrupted) as exc:  # the latter: Ctrl-C in a serial render
        _study_interrupted(Path(args.out), len(spec.points), exc)
        return interrupt_status(exc)
    print(
        f"study {s.name}: {s.ran} points run, {s.skipped} already done, {s.failed} failed, "
        f"{s.seconds:.1f} s -> {Path(args.out)}/{{{','.join(s.files)}}}"
    )
    return 1 if s.failed else 0


def _study_interrupted(out: Path, points: int, exc: BaseException) -> None:
    """Say how many points ``results.csv`` keeps, and whether the render cut short kept its
    finished steps (a serial study's capture saves them in its ``.partial``)."""

    try:
        saved = len(read_csv(out / RESULTS))
    except (OSError, ValueError):
        saved = 0
    why = str(exc).split(";")[0] if isinstance(exc, CaptureInterrupted) else "interrupted"
    kept = " (the render under way kept its finished steps)" if "saved in" in str(exc) else ""
    print(
        f"pacam study: {why}; {saved} of {points} points are saved in {out / RESULTS}{kept}: "
        "run the same command again to resume",
        file=sys.stderr,
    )
