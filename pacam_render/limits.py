"""Bounded work: estimate memory and effort before a long computation, and refuse what cannot
finish, naming the parameter that raises the limit (the CLI shows it as its flag).

Warnings that do not stop the work (more samples than asked, clipped pixels, ignored options)
are :class:`PacamWarning`: the CLI prints each as one ``note:`` line.
"""

from __future__ import annotations

import os
import shutil
import warnings
from pathlib import Path

from .errors import ParameterError

DEFAULT_MAX_STEPS = 20_000
"""Time steps of a moving capture (``--max-steps``): about 10 min of step overhead alone."""
DEFAULT_MAX_SAMPLES = 2**35
"""Camera samples of one capture (``--max-samples``): about 1.5 h at the 6 M samples/s that a
coded train render reaches on 2 cores."""


class PacamWarning(UserWarning):
    """Something the user should know that does not stop the work."""


def note(message: str, stacklevel: int = 2) -> None:
    """Warn with a :class:`PacamWarning`: a note for the user; the work goes on."""
    warnings.warn(message, PacamWarning, stacklevel=stacklevel + 1)


def show_notes(prefix: str = "note") -> None:
    """Print each :class:`PacamWarning` as one line, ``note: ...``, as the command line does
    (without Python's source path and line); other warnings as before. For scripts and
    notebooks.

    Examples
    --------
    >>> import sys, warnings
    >>> before = warnings.showwarning
    >>> show_notes()
    >>> warnings.showwarning(PacamWarning("spp raised to 8"), PacamWarning, "x.py", 1, sys.stdout)
    note: spp raised to 8
    >>> warnings.showwarning = before
    """
    default = warnings.showwarning
    if getattr(default, "_pacam_notes", False):
        default = default._pacam_default  # shown once, however often this is called

    def show(message, category, filename, lineno, file=None, line=None):
        if not issubclass(category, PacamWarning):
            return default(message, category, filename, lineno, file, line)
        import sys

        print(f"{prefix}: {message}", file=sys.stderr if file is None else file)

    show._pacam_notes, show._pacam_default = True, default
    warnings.showwarning = show


def available_bytes() -> int:
    """Memory the process can still use, bytes: the least of the machine's (MemAvailable of
    /proc/meminfo, else physical RAM), what its own limits leave (``ulimit -v`` and ``-d``:
    RLIMIT_AS and RLIMIT_DATA less its present size, where an allocation past them raises
    MemoryError) and what its control group leaves (cgroup v2 ``memory.max``, v1
    ``memory.limit_in_bytes``, less the usage that cannot be reclaimed)."""
    return max(0, int(min(_machine_bytes(), _rlimit_bytes(), _cgroup_bytes())))


def free_disk(path) -> tuple[Path, int]:
    """The free disk for ``path``, which may not exist yet: (its nearest existing folder,
    free bytes there)."""
    probe = Path(path)
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    return probe, int(shutil.disk_usage(probe).free)


def _machine_bytes() -> float:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def _rlimit_bytes() -> float:
    """What RLIMIT_AS (against VmSize) and RLIMIT_DATA (against VmData) leave; inf if unset."""
    import resource

    status = _proc_status()
    left = float("inf")
    for limit, key in ((resource.RLIMIT_AS, "VmSize"), (resource.RLIMIT_DATA, "VmData")):
        soft = resource.getrlimit(limit)[0]
        if soft != resource.RLIM_INFINITY and key in status:
            left = min(left, soft - status[key])
    return left


def _proc_status() -> dict[str, int]:
    """The ``Vm*`` sizes of /proc/self/status, bytes (empty where there is none)."""
    out = {}
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Vm") and line.rstrip().endswith("kB"):
                    key, value = line.split(":", 1)
                    out[key] = int(value.split()[0]) * 1024
    except OSError:
        pass
    return out


def _cgroup_bytes() -> float:
    """What this process's memory control group leaves (limit - usage + inactive file
    cache), cgroup v2 or v1; inf without a limit or a readable cgroup."""
    root = "/sys/fs/cgroup"
    try:
        with open("/proc/self/cgroup", encoding="ascii") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return float("inf")
    for line in lines:
        _, controllers, path = line.split(":", 2)
        if controllers == "":  # v2
            files = ("memory.max", "memory.current", "inactive_file")
            dirs = (f"{root}{path.rstrip('/')}", root)
        elif "memory" in controllers.split(","):  # v1
            files = ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
            dirs = (f"{root}/memory{path.rstrip('/')}", f"{root}/memory")
        else:
            continue
        for d in dirs:
            left = _cgroup_left(d, *files)
            if left is not None:
                return left
    return float("inf")


def _cgroup_left(folder: str, limit_file: str, usage_file: str, cache_key: str) -> float | None:
    try:
        with open(f"{folder}/{limit_file}", encoding="ascii") as fh:
            raw = fh.read().strip()
        if raw == "max" or int(raw) >= 2**60:
            return float("inf")
        with open(f"{folder}/{usage_file}", encoding="ascii") as fh:
            usage = int(fh.read().strip())
        cache = 0
        with open(f"{folder}/memory.stat", encoding="ascii") as fh:
            for line in fh:
                key, _, value = line.partition(" ")
                if key == cache_key:
                    cache = int(value)
        return int(raw) - usage + cache
    except (OSError, ValueError):
        return None


def gib(nbytes: float) -> str:
    """Bytes for a message: GiB to 3 digits (MiB below 1 GiB)."""
    if nbytes < 2**30:
        return f"{nbytes / 2**20:.3g} MiB"
    return f"{nbytes / 2**30:.3g} GiB"


def duration(seconds: float) -> str:
    """Seconds for a message: ``0.52 s``, ``42 s``, ``3.5 min`` or ``1.2 h``."""
    if seconds < 90:
        return f"{seconds:.2g} s" if seconds < 10 else f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.2g} min"
    return f"{seconds / 3600:.3g} h"


def check_memory(what: str, nbytes: float, flags: str) -> None:
    """Refuse work whose arrays would not fit in the memory available now.

    Parameters
    ----------
    what : str
        What needs the memory, e.g. ``"a 100000x75000 capture"``.
    nbytes : float
        The estimate, bytes.
    flags : str
        The parameters that shrink it, for the message.

    Raises
    ------
    ParameterError
        If ``nbytes`` exceeds :func:`available_bytes`.
    """
    free = available_bytes()
    if nbytes > free:
        raise ParameterError(
            f"{what} needs about {gib(nbytes)} of memory, and {gib(free)} is available; "
            f"reduce {flags}"
        )


def check_count(what: str, count: float, limit: int, flag: str, hint: str = "") -> None:
    """Refuse ``count`` units of work above ``limit``, naming the parameter (``flag``) that
    raises it."""
    if count > limit:
        raise ParameterError(
            f"{what}: {count:.4g}, above the limit of {limit} ({flag} raises it){hint}"
        )
