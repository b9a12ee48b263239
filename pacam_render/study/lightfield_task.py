"""A study task on one light-field store (``[render] lightfield = true``): the group's scene,
speed, depth and seed traced once through the whole lens, then each design and mode of the
group synthesised from it (:mod:`pacam_render.lightfield`) and its points scored as a rendered
capture's are. ``render_s`` of a row is the store's seconds plus its design's synthesis.
"""

from __future__ import annotations

import shutil
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path

from ..exposure.integrate import CaptureInterrupted
from ..lightfield import StoreSpec, render_lightfield, synthesize
from ..limits import PacamWarning
from .point import Task, capture_info, capture_inputs, error_rows, run_task, score_points


def run_study_task(task: Task) -> list[dict]:
    """A study task: on one light-field store when the study asks for it, else rendered
    (:func:`~.point.run_task`)."""
    return run_lightfield_task(task) if task.render.get("lightfield") else run_task(task)


def by_design(points) -> dict[tuple, list]:
    """The points grouped by the capture they are scored on: (mode, design)."""
    out: dict[tuple, list] = {}
    for p in points:
        out.setdefault((p.mode, p.design), []).append(p)
    return out


def run_lightfield_task(task: Task) -> list[dict]:
    """One store for ``task``'s group, then every design's capture from it (module docstring)."""

    t0 = time.perf_counter()
    folder = _store_folder(task)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)  # notes stay in the captures' records
        try:
            store, desc, base = _store(task, folder)
        except CaptureInterrupted:
            raise
        except Exception as exc:  # the group's points are reported, the study goes on
            return error_rows(task.points, exc, time.perf_counter() - t0)
        store_s = time.perf_counter() - t0
        rows = []
        for points in by_design(task.points).values():
            rows += _design_rows(store, desc, base, task, points, store_s)
    shutil.rmtree(folder, ignore_errors=True)  # the rows are written: the samples are not kept
    return rows


def _design_rows(store, desc, base: dict, task: Task, points, store_s: float) -> list[dict]:

    t1 = time.perf_counter()
    try:
        spec = capture_inputs(task.render, points[0])[0]
        cap = synthesize(store, spec, progress=False, description=desc)
        info = capture_info(cap, desc, base)
    except Exception as exc:
        return error_rows(points, exc, time.perf_counter() - t1)
    return score_points(cap, desc, info, task, points, store_s + time.perf_counter() - t1)


def _store(task: Task, folder: Path):
    """The group's store (resumed from ``folder``), its scene and the group's speed and depth."""

    inputs = [
        capture_inputs(task.render, ps[0]) for ps in by_design(task.group or task.points).values()
    ]
    specs = tuple(spec for spec, _, _ in inputs)
    _, desc, base = inputs[0]
    store_spec = StoreSpec(replace(specs[0], mode="coded"), designs=specs)
    store = render_lightfield(store_spec, folder, progress=False, description=desc)
    return store, desc, base


def _store_folder(task: Task) -> Path:
    """Where the group's store is kept while the task runs: beside its render's checkpoint
    (a re-run resumes it), else a temporary folder."""
    if task.partial_dir is None:
        return Path(tempfile.mkdtemp(prefix="pacam_store."))
    return Path(task.partial_dir).parent / "store"
