"""The engine that runs independent tasks: Dask distributed, or serially in-process.

* Default: a ``LocalCluster`` started here with ``workers`` processes (spawned, since Mitsuba's
  JIT is not fork-safe), one task at a time each, and Dr.Jit's thread count on each worker set
  to cores / workers before each task.
* ``scheduler``: an existing Dask cluster by address (``dask scheduler`` / ``dask worker``, or
  dask-jobqueue on SLURM); its workers need pacam_render installed.
* ``workers=0``: in this process, one task after another (for debugging).
* ``client``: a ``distributed.Client`` of your own (a notebook's cluster), left open.

:func:`open_client` can serve the LocalCluster's dashboard (with bokeh); :func:`dashboard_link`
gives its address.

A worker process runs one task at a time, even with several threads (a lock around each
task): Mitsuba's JIT state is the process's. A task whose worker dies is retried once by the
scheduler (``allowed-failures = 1`` on the embedded cluster; a cluster of your own keeps its
own setting); if it dies again its result is the exception (``KilledWorker``), handed to
``on_done`` like any result, and the rest go on.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import uuid
import warnings
from collections.abc import Callable, Iterator, Sequence

from ..errors import ParameterError
from ..limits import PacamWarning, available_bytes

CONNECT_TIMEOUT_S = 10.0
"""How long to wait for a ``--scheduler`` to answer, s."""
ALLOWED_FAILURES = 1
"""Worker deaths a task may cause before it is given up (1: one retry)."""


def default_workers() -> int:
    """One worker per core."""
    return max(1, os.cpu_count() or 1)


def threads_per_worker(workers: int) -> int:
    """Dr.Jit threads for each of ``workers`` processes on this machine: cores / workers."""
    return max(1, (os.cpu_count() or 1) // max(1, workers))


WORKER_BYTES = 1 << 30
"""Memory a worker process needs (Mitsuba, Dr.Jit and one capture's arrays): about 1 GiB."""


def check_workers(workers: int | None, n_tasks: int | None = None) -> int:
    """``workers``: an integer >= 0 (0: serial). By default one per core, no more than there
    are tasks, and 0 (no cluster to start) for a single task. More than there are tasks,
    cores, or memory for (:data:`WORKER_BYTES` each) is clamped to that, with a note, before
    any process starts: more processes only compete for the same cores."""
    if workers is None:
        if n_tasks is not None and n_tasks <= 1:
            return 0
        return min(default_workers(), n_tasks or default_workers())
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise ParameterError(f"`workers` must be an integer >= 0 (0: serial), got {workers!r}")
    limits = {"cores": default_workers(), "memory": max(1, available_bytes() // WORKER_BYTES)}
    if n_tasks is not None:
        limits["tasks"] = max(1, n_tasks)
    bound = min(limits.values())
    if workers > bound:
        why = ", ".join(f"{v} {k}" for k, v in limits.items())
        warnings.warn(
            f"`workers` {workers} is more than this run can use ({why}): using {bound}",
            PacamWarning,
            stacklevel=2,
        )
        return bound
    return workers


def check_scheduler(address: str | None) -> str | None:
    """``--scheduler``: None, or a Dask address with a port (``tcp://host:8786``)."""
    if address is None:
        return None
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(str(address))
        if scheme in ("tcp", "tls"):
            parse_host_port(loc)  # raises without a port
    except ValueError as exc:
        raise ParameterError(
            f"`scheduler` must be a Dask scheduler's address, e.g. tcp://host:8786, got "
            f"{address!r} ({exc})"
        ) from None
    return address


def probe_scheduler(address: str | None, timeout: float | None = None) -> None:
    """Refuse ``address`` unless a Dask scheduler answers there within ``timeout`` seconds.

    Dask's own handshake has no time limit and trusts the first bytes it reads: a web server
    there makes it wait for ever, or read "HTTP/1.0" as the length of an exabyte frame
    (MemoryError). So a bounded exchange asks the service who it is first.

    Parameters
    ----------
    address : str or None
        The scheduler's address, e.g. ``tcp://host:8786``; None (no scheduler) passes.
    timeout : float, optional
        Seconds for the whole exchange (default :data:`CONNECT_TIMEOUT_S`).

    Raises
    ------
    ParameterError
        If nothing answers in time, or what answers is not a Dask scheduler.
    """
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    if check_scheduler(address) is None:
        return
    limit = CONNECT_TIMEOUT_S if timeout is None else timeout
    # its own thread and event loop: the caller may be running one (a notebook)
    with ThreadPoolExecutor(1, thread_name_prefix="pacam-probe") as pool:
        job = pool.submit(asyncio.run, _ask_identity(address, limit))
        try:
            kind = job.result()
        except TimeoutError:
            kind = "nothing answered in Dask's protocol"
        except OSError as exc:
            kind = f"{type(exc).__name__}: {exc}"
        except (MemoryError, Exception) as exc:  # bytes of another protocol read as frames
            kind = f"it answers in another protocol: {type(exc).__name__} reading its reply"
    if kind != "Scheduler":
        raise ParameterError(
            f"`scheduler` {address}: no Dask scheduler answered within {limit:g} s ({kind})"
        )


async def _ask_identity(address: str, limit: float) -> str:
    """The ``type`` that the Dask server at ``address`` gives for itself (``Scheduler``)."""
    import asyncio

    from distributed.comm import connect

    async def ask() -> str:
        comm = await connect(address, timeout=limit)
        try:
            await comm.write({"op": "identity", "reply": True})
            reply = await comm.read()
        finally:
            comm.abort()
        kind = reply.get("type") if isinstance(reply, dict) else None
        if kind == "Scheduler":
            return kind
        return f"a Dask {kind} answered" if kind else f"it answered {str(reply)[:60]!r}"

    try:
        return await asyncio.wait_for(ask(), limit)
    except asyncio.TimeoutError:
        raise TimeoutError from None


def run_tasks(
    fn: Callable,
    tasks: Sequence,
    on_done: Callable,
    workers: int = 0,
    scheduler: str | None = None,
    threads: int | None = None,
    client=None,
) -> None:
    """Run ``fn(task)`` for every task; call ``on_done(task, result)`` here as each finishes.

    Parameters
    ----------
    fn : callable
        A module-level function (workers import it by name).
    tasks : sequence
        Picklable arguments, one per task.
    on_done : callable
        Called in this process with the task and its result, or the exception it raised.
    workers : int, optional
        Processes of the embedded LocalCluster; 0 runs serially here.
    scheduler : str, optional
        The address of an existing Dask scheduler (``tcp://host:8786``); ``workers`` is
        then ignored.
    threads : int, optional
        Dr.Jit threads per worker of the LocalCluster (default cores / workers).
    client : distributed.Client, optional
        A client to run on (left open); ``workers`` and ``scheduler`` are then ignored, and
        ``threads`` is set on its workers only if given.

    Raises
    ------
    ParameterError
        If the scheduler does not answer within :data:`CONNECT_TIMEOUT_S`.
    KeyboardInterrupt
        On Ctrl-C; the tasks under way are cancelled, and finished ones were handed on.
    """
    if client is None and scheduler is None and workers == 0:
        for task in tasks:
            on_done(task, fn(task))
        return
    if client is None and scheduler is not None:
        threads = None  # a cluster of your own keeps its workers' settings
    elif client is None and threads is None:
        threads = threads_per_worker(workers)  # (a client given: ``threads`` as given)
    with open_client(workers, scheduler, client) as client:
        _submit_all(client, fn, tasks, on_done, threads)


def _submit_all(client, fn: Callable, tasks: Sequence, on_done: Callable, threads) -> None:
    """Submit every task to ``client``; hand each result (or exception) on as it finishes."""
    from distributed import as_completed

    tag = uuid.uuid4().hex[:8]
    futures = {
        client.submit(_call, fn, t, threads, pure=False, key=f"pacam-{tag}-{i}"): t
        for i, t in enumerate(tasks)
    }
    try:
        for fut in as_completed(futures):
            try:
                result = fut.result()
            except Exception as exc:  # KilledWorker, or an error outside fn's own handling
                result = exc
            on_done(futures[fut], result)
    except BaseException:
        client.cancel(list(futures))
        raise


_ONE_AT_A_TIME = threading.Lock()
"""Held while a task runs: a worker process runs one pacam task at a time, whatever its
thread count. A client of your own may give a worker several threads (LocalCluster's default
on 2 cores: 2), and Mitsuba's variant and Dr.Jit's JIT state are the process's: two renders at
once in one process are the likely cause of points that failed only under load."""


def _call(fn: Callable, task, threads: int | None):
    """``fn(task)`` on a worker, one at a time per process (:data:`_ONE_AT_A_TIME`), with
    Dr.Jit's thread count set first (cores / workers)."""
    with _ONE_AT_A_TIME:
        if threads:
            import drjit as dr

            dr.set_thread_count(int(threads))
        return fn(task)


@contextlib.contextmanager
def open_client(workers: int, scheduler: str | None = None, client=None) -> Iterator:
    """The Dask client that runs tasks: ``client`` itself (left open), one connected to
    ``scheduler``, a LocalCluster of ``workers`` processes (closed on exit), or None when
    ``workers`` is 0 (serial). A LocalCluster serves its dashboard on a free port (with
    bokeh; :func:`dashboard_link`)."""
    if client is not None:
        yield client
        return
    if scheduler is None and workers == 0:
        yield None
        return
    with _client(workers, scheduler) as made:
        yield made


def dashboard_link(client) -> str | None:
    """The address of ``client``'s Dask dashboard, or None where it serves none."""
    if client is None:
        return None
    try:
        info = client.scheduler_info()
    except Exception:  # noqa: BLE001 - a dashboard is a convenience, never a failure
        return None
    served = info.get("services", {}).get("dashboard") and _has_bokeh()
    return client.dashboard_link if served else None


@contextlib.contextmanager
def _client(workers: int, scheduler: str | None) -> Iterator:
    import dask
    from distributed import Client, LocalCluster

    if scheduler is not None:
        probe_scheduler(scheduler)  # bounded: Dask's own handshake can wait for ever
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError, MemoryError) as exc:
            raise ParameterError(
                f"`scheduler` {scheduler}: no Dask scheduler answered within "
                f"{CONNECT_TIMEOUT_S:g} s ({type(exc).__name__}: {exc})"
            ) from None
        with client:
            yield client
        return
    config = {
        "distributed.worker.multiprocessing-method": "spawn",  # Mitsuba's JIT is not fork-safe
        "distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
    }
    with dask.config.set(config):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # a free port: the HTTP server runs in any case
            silence_logs=logging.ERROR,
        )
        with cluster, Client(cluster) as client:
            yield client


def _has_bokeh() -> bool:
    import importlib.util

    return importlib.util.find_spec("bokeh") is not None
