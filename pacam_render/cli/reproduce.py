"""``pacam reproduce``: the paper's simulation figures (CSV, PNG, Markdown)."""

from __future__ import annotations

import argparse

from ..errors import ParameterError
from ..experiments import reproduce
from ..experiments.reproduce import FIGURES
from ..io.outputs import writable_dir
from ..study.engine import check_workers, probe_scheduler
from .common import add_engine_args, add_force, add_out


def add(sub) -> None:

    p = sub.add_parser("reproduce", help="the paper's simulation figures: CSV, PNG, Markdown")
    p.add_argument("figure", choices=[*FIGURES, "all"])
    p.add_argument("--quick", action="store_true", help="fewer images and points (< 1 min each)")
    add_out(p)
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    add_engine_args(p)
    add_force(p, "overwrite existing figure files")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    names = list(reproduce.FIGURES) if args.figure == "all" else [args.figure]
    if not 0 <= args.seed < 2**31:
        raise ParameterError(f"--seed must be an integer in [0, 2^31), got {args.seed}")
    workers = check_workers(args.workers, len(names))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    out = writable_dir(args.out)
    for fig in reproduce.run(
        names, out, args.quick, args.force, args.seed, workers, args.scheduler
    ):
        print(f"{fig.name}: {out / fig.name}.csv .png .md ({fig.seconds:.1f} s)")
    return 0
