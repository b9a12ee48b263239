"""Rendered studies: sweeps through the ray tracer, the image sensor and deconvolution, scored
against each capture's ground truth, run as independent tasks on Dask (``pacam study``).

:mod:`.spec` parses a study (TOML), :mod:`.point` runs one task, :mod:`.score` scores it,
:mod:`.engine` runs the tasks, :mod:`.results` keeps ``results.csv`` and :mod:`.report` writes
``report.md`` and the plots.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from .engine import check_workers, run_tasks
from .point import Task, point_row, run_task
from .results import Results
from .spec import StudySpec, builtin_studies, load_study

__all__ = ["StudySummary", "builtin_studies", "load_study", "run_study"]


@dataclass
class StudySummary:
    """What a run of a study did: points in all, skipped as done, run, ok and failed."""

    name: str
    points: int
    skipped: int = 0
    ran: int = 0
    failed: int = 0
    seconds: float = 0.0
    files: list[str] = field(default_factory=list)


def run_study(
    spec: StudySpec,
    out: str | Path,
    workers: int | None = None,
    scheduler: str | None = None,
    keep_images: bool = False,
    force: bool = False,
    progress: bool = True,
    threads: int | None = None,
) -> StudySummary:
    """Run the points of ``spec`` not yet finished in ``out``, then write the report.

    Parameters
    ----------
    spec : StudySpec
        The study (:func:`load_study`).
    out : path-like
        The results folder: ``results.csv``, ``study.json``, ``report.md``, plots, and with
        ``keep_images`` an ``images/`` folder of EXRs. Locked while the study runs.
    workers : int, optional
        LocalCluster processes (default: one per core); 0 runs serially in this process.
    scheduler : str, optional
        Address of an existing Dask scheduler instead of the LocalCluster.
    keep_images, force, progress : bool, optional
        Keep each point's layers as EXR; start afresh over other results in ``out``; show a
        progress bar with an ETA.
    threads : int, optional
        Dr.Jit threads per LocalCluster worker (default cores / workers).

    Returns
    -------
    StudySummary

    Raises
    ------
    ParameterError
        If ``out`` is in use, holds another study's results, or the scheduler is unreachable.
    KeyboardInterrupt
        On Ctrl-C; every finished point is already in ``results.csv``.
    """
    from tqdm import tqdm

    from ..io.lock import output_lock
    from ..io.outputs import writable_dir
    from .report import write_report

    workers = check_workers(workers)
    out = writable_dir(out)
    t0 = time.perf_counter()
    with output_lock(out):
        results = Results(out, spec, force)
        tasks = _tasks(spec, results.done(), out if keep_images else None)
        summary = StudySummary(spec.name, len(spec.points), skipped=len(results.done()))
        todo = sum(len(t.points) for t in tasks)
        bar = tqdm(total=todo, unit="point", desc=spec.name, disable=not progress, smoothing=0)

        def done(task: Task, rows) -> None:
            if isinstance(rows, BaseException):  # the worker died twice, or Dask failed it
                rows = _failed_rows(task, rows)
            results.add(rows)
            summary.ran += len(rows)
            summary.failed += sum(r["status"] != "ok" for r in rows)
            bar.update(len(rows))

        with bar:
            run_tasks(run_task, tasks, done, workers, scheduler, threads)
        summary.files = write_report(spec, out)
    summary.seconds = time.perf_counter() - t0
    return summary


def _tasks(spec: StudySpec, done: set[int], keep: Path | None) -> list:
    tasks = []
    for k, group in enumerate(spec.groups()):
        todo = tuple(p for p in group if p.index not in done)
        if todo:
            where = None if keep is None else str(keep / "images" / f"render_{k:04d}")
            tasks.append(Task(spec.render, todo, where))
    return tasks


def _failed_rows(task: Task, exc: BaseException) -> list[dict]:
    status = f"failed: {type(exc).__name__}: {exc}"
    return [point_row(p, {}, status, 0.0, 0.0) for p in task.points]
