"""Rendering a dataset: its renders on Dask (:mod:`pacam_render.study.engine`), resumable by
key, interrupt-safe, with failed samples recorded and retried.

The folder holds ``dataset.json`` (the spec's key and document: another spec is refused
without ``force``), ``index.csv`` (:mod:`.index`), ``samples/<id>/`` (:mod:`.sample`),
``scenes/`` (a family's generated scenes) and ``card.md`` (:mod:`.card`). A sample whose
folder records its key is skipped; a failed one is rendered again on the next run.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ParameterError
from ..exposure.render_time import estimate_capture
from ..io.arrays import read_json
from ..io.lock import check_unlocked, output_lock
from ..io.outputs import writable_dir, write_json
from ..limits import DEFAULT_MAX_SAMPLES, DEFAULT_MAX_STEPS, duration, gib, note
from ..scenes import load_scene
from ..scenes.family import family_scene
from ..study.engine import check_scheduler, check_workers, run_tasks
from .card import write_card
from .index import read_index, row, write_index
from .plan import DatasetPlan, check_disk, plan_dataset, store_ratio
from .sample import RenderTask, finished, render_task
from .spec import DatasetSpec

DATASET_JSON = "dataset.json"


@dataclass
class RunSummary:
    """What a run did: samples in the plan, skipped as done, rendered ok, failed; seconds."""

    samples: int = 0
    skipped: int = 0
    rendered: int = 0
    failed: int = 0
    seconds: float = 0.0
    estimate_s: float | None = None
    rows: list = field(default_factory=list)


def run_dataset(
    spec: DatasetSpec,
    out,
    workers: int | None = None,
    scheduler: str | None = None,
    force: bool = False,
    progress: bool = True,
    client=None,
) -> RunSummary:
    """Render the samples of ``spec`` into folder ``out`` that are not there yet.

    Parameters
    ----------
    spec : DatasetSpec
        The dataset (:func:`~.spec.load_spec`).
    out : path-like
        The dataset's folder (created).
    workers : int, optional
        Processes of a Dask LocalCluster (0: serially in this process; default one per core,
        no more than there are renders).
    scheduler : str, optional
        An existing Dask scheduler's address; ``workers`` is then ignored.
    force : bool, optional
        Take over a folder made from another spec (its samples of the same key are kept).
    progress : bool, optional
        A progress bar over the samples, with the time left.
    client : distributed.Client, optional
        A client of your own (left open).

    Returns
    -------
    RunSummary

    Raises
    ------
    ParameterError
        Before any render: the folder holds another spec's dataset (without ``force``), or the
        samples exceed the disk or memory bounds, or a scene or camera cannot be built.
    """
    t0 = time.perf_counter()
    out = Path(out)
    plan = plan_dataset(spec)
    check_scheduler(scheduler)
    _check_folder(out, spec, force)
    with output_lock(out):
        write_json(out / DATASET_JSON, _identity(spec), force=True)
        files = scene_files(spec, out)
        done, rows = _resume(plan, out)
        tasks = _tasks(plan, out, done, files)
        todo = sum(len(t.todo) for t in tasks)
        per = max(plan.bytes_per_sample.values())
        check_disk(todo * per, spec.max_disk_gib, out)
        own = tasks and scheduler is None and client is None
        n = check_workers(workers, len(tasks)) if own else 0
        summary = RunSummary(samples=len(plan.samples), skipped=len(done))
        summary.estimate_s = _estimate(tasks, max(n, 1), progress) if tasks else 0.0
        _render_all(tasks, plan, out, rows, summary, (n, scheduler, client), progress)
        _remove_empty(out / ".renders")
        _remove_empty(out / ".stores")
        summary.seconds = time.perf_counter() - t0
        summary.rows = _ordered(plan, rows)
        write_card(out, spec, summary.rows, scene_cards(files))
    return summary


def _identity(spec: DatasetSpec) -> dict:
    return {"name": spec.name, "key": spec.key(), "samples": spec.n_samples, "spec": spec.source}


def _check_folder(out: Path, spec: DatasetSpec, force: bool) -> None:
    """Refuse a folder that holds another spec's dataset (without ``force``), or other files."""
    writable_dir(out, "`out`", create=False)
    check_unlocked(out)
    meta = out / DATASET_JSON
    if meta.is_file():
        old = read_json(meta, "the dataset's")
        if old.get("key") != spec.key() and not force:
            raise ParameterError(
                f"`out` {out} holds a dataset of another spec ({old.get('name')!r}, key "
                f"{old.get('key')}); pass `force=True` to render this spec there (samples of the "
                "same key are kept), or choose another folder"
            )
    elif out.is_dir() and any(p.name != ".pacam.lock" for p in out.iterdir()) and not force:
        raise ParameterError(f"`out` {out} holds other files; choose a new folder, or `force=True`")


def scene_files(spec: DatasetSpec, out: Path) -> dict[str, str]:
    """A family's scenes generated into ``out/scenes`` (scene string -> scene.xml); empty for
    listed scenes, which load by name or path."""
    if spec.family is None:
        return {}
    files = {}
    for scene in spec.scenes:
        seed = int(scene.rsplit(":", 1)[1])
        path = family_scene(spec.family, seed, spec.family_params, cache_dir=out / "scenes")
        files[scene] = str(path)
    return files


def scene_cards(files: dict[str, str]) -> list[dict]:
    """The ``scene.json`` cards beside the generated scenes (those that have one)."""
    cards = []
    for path in files.values():
        card = Path(path).parent / "scene.json"
        if card.is_file():
            cards.append(read_json(card, "the scene card"))
    return cards


def _resume(plan: DatasetPlan, out: Path) -> tuple[set[str], dict[str, dict]]:
    """The ids of finished samples (their folder records their key), and the rows to keep:
    theirs, and the failed rows of this plan's samples until they run again."""
    old = {r["id"]: r for r in read_index(out)}
    done, rows = set(), {}
    for s in plan.samples:
        ok = finished(out, s)
        if ok is not None:
            done.add(s.id)
            rows[s.id] = ok
        elif s.id in old and old[s.id].get("key") == s.key:
            rows[s.id] = old[s.id]  # failed before: kept until its retry finishes
    stray = set(old) - {s.id for s in plan.samples}
    if stray:
        note(f"{len(stray)} index rows of an earlier spec are not in this one: dropped from "
             "index.csv (their folders stay under samples/)")  # fmt: skip
    return done, rows


def _tasks(plan: DatasetPlan, out: Path, done: set[str], files: dict) -> list[RenderTask]:
    spec = plan.spec
    target = None
    if spec.noise_ratio is not None:
        target = {"ratio": spec.noise_ratio, "levels": list(spec.light_levels)}
    elif spec.noise_target is not None:
        target = {"sigma": spec.noise_target}
    tasks = []
    for group in _groups(plan.renders):
        todo = tuple(s.id for r in group for s in r.samples if s.id not in done)
        if todo:
            tasks.append(RenderTask(
                group, todo, str(out), spec.sensor, target, spec.psf_velocity_px_per_ms,
                files.get(group[0].scene), spec.max_samples or DEFAULT_MAX_SAMPLES,
                spec.max_steps or DEFAULT_MAX_STEPS,
            ))  # fmt: skip
    return tasks


def _groups(renders) -> list[tuple]:
    """The renders a task takes: one direct render, or a scene's renders through its store
    (all of them again when one of its samples is missing: the store serves them at once)."""
    out, stores = [], {}
    for r in renders:
        if r.via == "store":
            stores.setdefault(r.scene, []).append(r)
        else:
            out.append((r,))
    return [tuple(g) for g in stores.values()] + out


def _estimate(tasks: list[RenderTask], workers: int, progress: bool) -> float:
    """The renders' predicted wall time, s: each camera's first render estimated before any
    work (:func:`~pacam_render.exposure.render_time.estimate_capture`; a noise target's
    pilot only), times its renders, shared among ``workers``. Loading the scene here also
    refuses a bad scene before any render."""
    first: dict[str, float] = {}
    total = 0.0
    for t in tasks:
        for r in t.renders:
            if r.camera not in first:
                desc = load_scene(t.scene_file or r.scene)
                est = estimate_capture(r.spec, desc, t.target is not None, True, t.max_steps)
                first[r.camera] = est.seconds
        direct = sum(first[r.camera] for r in t.renders)
        total += direct * (store_ratio(len(t.renders)) if t.store else 1.0)
    seconds = total / workers
    if progress:
        what = " (the noise target's pilots only)" if tasks[0].target else ""
        stores = sum(t.store for t in tasks)
        what += f", {stores} through light-field stores (RESULTS.md's ratios)" if stores else ""
        print(f"estimate: about {duration(seconds)} for {len(tasks)} renders on {workers} "
              f"worker(s){what}", file=sys.stderr)  # fmt: skip
    return seconds


def _render_all(tasks, plan, out: Path, rows: dict, summary: RunSummary, how, progress) -> None:
    """Run every task; each finished render's rows go to index.csv at once."""
    from tqdm import tqdm

    if not tasks:
        return
    workers, scheduler, client = how
    bar = tqdm(total=sum(len(t.todo) for t in tasks), unit="sample", desc=plan.spec.name,
               disable=not progress, smoothing=0, file=sys.stderr)  # fmt: skip

    def done(task: RenderTask, result) -> None:
        if isinstance(result, BaseException):  # the worker died twice, or Dask failed it
            result = [row(s, "failed", f"{type(result).__name__}: {result}")
                      for s in task.samples()]  # fmt: skip
        for r in result:
            rows[r["id"]] = r
            summary.rendered += r["status"] == "ok"
            summary.failed += r["status"] != "ok"
        write_index(out, _ordered(plan, rows))
        bar.update(len(result))

    with bar:
        run_tasks(render_task, tasks, done, workers, scheduler, client=client)


def _remove_empty(folder: Path) -> None:
    """Remove the renders' checkpoint (or stores') folder when nothing was left in it."""
    if folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()


def _ordered(plan: DatasetPlan, rows: dict) -> list[dict]:
    return [rows[s.id] for s in plan.samples if s.id in rows]


def disk_line(plan: DatasetPlan) -> str:
    """``N samples (S scenes x C cameras x L light levels), about X of disk``."""
    spec = plan.spec
    return (
        f"{len(plan.samples)} samples ({len(spec.scenes)} scenes x {len(spec.cameras)} cameras "
        f"x {len(spec.light_levels)} light levels), at most {gib(plan.disk_bytes)} of disk"
    )
