"""Rendered studies: sweeps through the ray tracer, the image sensor and deconvolution, scored
against each capture's ground truth, run as independent tasks on Dask (``pacam study``).

:mod:`.spec` parses a study (TOML), :mod:`.point` runs one task, :mod:`.score` scores it,
:mod:`.engine` runs the tasks, :mod:`.results` keeps ``results.csv`` and :mod:`.report` writes
``report.md`` and the plots.
"""

from __future__ import annotations

import sys
import time
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from ..errors import ParameterError, check_positive
from ..exposure.render_time import estimate_capture, say
from ..io.lock import output_lock
from ..io.outputs import writable_dir
from ..limits import duration
from .engine import (
    check_workers,
    dashboard_link,
    open_client,
    run_tasks,
    threads_per_worker,
)
from .lightfield_task import run_study_task as run_task  # rendered, or on a store
from .point import Task, capture_inputs, pilot_task, point_row, render_target
from .report import write_report
from .results import Results
from .spec import StudySpec, builtin_studies, load_study

__all__ = ["StudySummary", "builtin_studies", "load_study", "run_study"]

OVERHEAD = 1.2
"""A render's whole task over its capture's own passes: the ground truth (its sharp layer, to
the same noise in white units, and the aov layers) and the scoring."""


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
    estimate_s: float | None = None
    """The cost of the renders still to do, predicted from their pilot passes, s."""
    dashboard: str | None = None
    """The address of the Dask dashboard that showed the run (None: serial, or no bokeh)."""
    set_aside: int = 0
    """Rows of an edited spec's earlier run that no point has now, kept in a backup CSV."""


def run_study(
    spec: StudySpec,
    out: str | Path,
    workers: int | None = None,
    scheduler: str | None = None,
    keep_images: bool = False,
    force: bool = False,
    progress: bool = True,
    threads: int | None = None,
    budget_hours: float | None = None,
    on_estimate=None,
    client=None,
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
    budget_hours : float, optional
        Refuse the study when its renders, predicted from their pilot passes, would take
        longer (hours of wall time). The pilots are kept, so a re-run does not repeat them.
    on_estimate : callable, optional
        Called with the :class:`StudySummary` once the cost is estimated (before the renders).
    client : distributed.Client, optional
        Run on this Dask client (a cluster of your own, left open) instead of ``workers`` or
        ``scheduler``. Otherwise one cluster serves the pilots and the renders; the address
        of its dashboard (served when bokeh is installed) is printed with the progress and
        kept in ``StudySummary.dashboard``.

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

    workers = check_workers(workers)
    if budget_hours is not None:
        check_positive("budget_hours", budget_hours, "h")
    out = writable_dir(out)
    t0 = time.perf_counter()
    with output_lock(out):
        results = Results(out, spec, force)
        tasks = _tasks(spec, results.done(), out, keep_images)
        summary = StudySummary(spec.name, len(spec.points), skipped=len(results.done()))
        summary.set_aside = results.set_aside
        cluster = open_client(workers, scheduler, client) if tasks else nullcontext()
        with cluster as dask_client:
            own = scheduler is None and client is None
            run = _runner(dask_client, workers, threads, own, summary, progress)
            if spec.render.get("noise_ratio") and tasks:
                share = workers if own else 1
                _estimate_within_budget(
                    tasks, run, share, summary, budget_hours, on_estimate, progress
                )
            _render_all(tasks, run, results, summary, spec.name, progress)
        summary.files = write_report(spec, out)
    summary.seconds = time.perf_counter() - t0
    return summary


def _runner(dask_client, workers: int, threads: int | None, own: bool, summary, progress: bool):
    """``run_tasks`` bound to the client and the threads per worker (default cores / workers
    on a cluster of our own); the dashboard's address goes to ``summary`` and is printed."""
    from tqdm import tqdm

    summary.dashboard = dashboard_link(dask_client)
    if summary.dashboard and progress:
        tqdm.write(f"Dask dashboard: {summary.dashboard}", file=sys.stderr)
    threads = threads or (threads_per_worker(workers) if own and dask_client is not None else None)
    return partial(run_tasks, workers=workers, threads=threads, client=dask_client)


def _estimate_within_budget(
    tasks, run, share: int, summary, budget_hours, on_estimate, progress: bool
) -> None:
    """The estimate and budget step: the pilot passes predict the renders' wall time
    (``summary.estimate_s``), shown to ``on_estimate``, then refused over ``budget_hours``."""
    summary.estimate_s = _estimate(tasks, run, share, progress)
    if on_estimate is not None:
        on_estimate(summary)
    _check_budget(summary.estimate_s, budget_hours)


def _render_all(tasks: list, run, results, summary, name: str, progress: bool) -> None:
    """Render every task's points; each finished row goes to ``results`` at once."""
    from tqdm import tqdm

    todo = sum(len(t.points) for t in tasks)
    bar = tqdm(total=todo, unit="point", desc=name, disable=not progress, smoothing=0)

    def done(task: Task, rows) -> None:
        if isinstance(rows, BaseException):  # the worker died twice, or Dask failed it
            rows = _failed_rows(task, rows)
        results.add(rows)
        summary.ran += len(rows)
        summary.failed += sum(r["status"] != "ok" for r in rows)
        bar.update(len(rows))

    with bar:
        run(run_task, tasks, done)


def _tasks(spec: StudySpec, done: set[int], out: Path, keep: bool) -> list:
    tasks = []
    for k, group in enumerate(spec.groups()):
        todo = tuple(p for p in group if p.index not in done)
        if todo:
            where = str(out / "images" / f"render_{k:04d}") if keep else None
            partial = str(out / ".renders" / f"render_{k:04d}" / ".partial")
            tasks.append(
                Task(spec.render, todo, where, partial, spec.decompose, group, spec.model_error)
            )
    return tasks


def _estimate(tasks: list, run, workers: int, progress: bool) -> float:
    """Run every task's pilot passes (kept for its render), and predict the wall time of the
    renders: each render's planned passes (one of their steps timed) x :data:`OVERHEAD`,
    shared among ``workers`` (a serial run's pilots ran on every core, a worker's on its
    share; a cluster of your own counts as one)."""
    from tqdm import tqdm

    costs: list[float] = []
    if progress:
        _say_pilots(tasks, workers)
    bar = tqdm(total=len(tasks), unit="pilot", desc="pilot passes", disable=not progress)

    def done(task: Task, result) -> None:
        if isinstance(result, BaseException):
            return  # the render itself will report the error
        costs.append(result["predicted_seconds"] * OVERHEAD)
        bar.update(1)

    with bar:
        run(_safe_pilot, tasks, done)
    return sum(costs) / max(1, workers)


def _say_pilots(tasks: list, workers: int) -> None:
    """Say the pilot passes' predicted time (:mod:`~pacam_render.exposure.render_time`) before they
    run; a task whose inputs fail is left to its render to report."""

    total, rates = 0.0, None
    for i, task in enumerate(tasks):
        try:
            spec, desc, _ = capture_inputs(task.render, task.points[0])
            targeted = render_target(task.render, task.group or task.points) is not None
            est = estimate_capture(spec, desc, targeted, truth=False, first=i < max(1, workers))
        except Exception:  # noqa: BLE001 - the render reports it, with its point
            continue
        total, rates = total + est.seconds, est.rates
    if rates is not None:
        say(f"estimate: {len(tasks)} pilot passes about {duration(total / max(1, workers))} "
            f"(at the rates of {rates.basis}); they then predict the renders")  # fmt: skip


def _safe_pilot(task: Task):
    """A pilot, or the exception it raised (reported by the render later)."""
    try:
        return pilot_task(task)
    except Exception as exc:  # noqa: BLE001 - a bad point is the render's to report
        return exc


def _check_budget(estimate_s: float, budget_hours: float | None) -> None:
    if budget_hours is not None and estimate_s > budget_hours * 3600:
        raise ParameterError(
            f"the study's renders would take about {duration(estimate_s)} (predicted from "
            f"their pilot passes, which are kept), over budget_hours = {budget_hours:g} h; "
            "raise it, or make the study cheaper (in its file: a tighter [render] crop, a "
            "larger [render] noise_ratio, fewer points)"
        )


def _failed_rows(task: Task, exc: BaseException) -> list[dict]:
    status = f"failed: {type(exc).__name__}: {exc}"
    return [point_row(p, {}, status, 0.0, 0.0) for p in task.points]
