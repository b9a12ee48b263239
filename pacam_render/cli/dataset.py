"""``pacam dataset``: coded captures with their ground truth, scenes x cameras x light levels,
rendered on Dask into a folder that resumes (:mod:`pacam_render.dataset`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..dataset import load_spec, plan_dataset, run_dataset
from ..dataset.index import read_index
from ..dataset.run import disk_line
from ..exposure.integrate import CaptureInterrupted
from ..study.engine import check_scheduler, probe_scheduler
from .common import add_engine_args, add_force, add_out, add_quiet, interrupt_status


def add(sub) -> None:
    p = sub.add_parser(
        "dataset",
        help="a dataset of coded captures with their ground truth (sensor images, layers, PSF)",
    )
    p.add_argument("spec", metavar="SPEC.toml", help="the dataset's spec (docs/howto/dataset.md)")
    add_out(p, help="the dataset's folder: index.csv, card.md, samples/<id>/")
    add_engine_args(p)
    add_force(p, "render this spec into a folder made from another spec (same-key samples stay)")
    add_quiet(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    check_scheduler(args.scheduler)
    spec = load_spec(args.spec)  # every key checked before any work
    plan = plan_dataset(spec)  # and the disk and memory bounds
    probe_scheduler(args.scheduler)
    print(f"dataset {spec.name}: {disk_line(plan)}", flush=True)
    try:
        s = run_dataset(spec, args.out, args.workers, args.scheduler, args.force, not args.quiet)
    except (KeyboardInterrupt, CaptureInterrupted) as exc:
        _interrupted(Path(args.out), spec.n_samples, exc)
        return interrupt_status(exc)
    print(
        f"dataset {spec.name}: {s.rendered} samples rendered, {s.skipped} already done, "
        f"{s.failed} failed, {s.seconds:.1f} s -> {args.out}/{{index.csv,card.md,samples/}}"
    )
    if s.failed:
        print(f"dataset {spec.name}: run the same command again to retry the failed samples")
    return 1 if s.failed else 0


def _interrupted(out: Path, samples: int, exc: BaseException) -> None:
    """Say how many samples the index keeps, and that the same command resumes."""
    try:
        saved = sum(r["status"] == "ok" for r in read_index(out))
    except (OSError, ValueError):
        saved = 0
    why = str(exc).split(";")[0] if isinstance(exc, CaptureInterrupted) else "interrupted"
    print(
        f"pacam dataset: {why}; {saved} of {samples} samples are saved in {out}: run the same "
        "command again to resume",
        file=sys.stderr,
    )
