"""Bounded work: estimate memory and effort before a long computation, and refuse what cannot
finish, naming the parameter that raises the limit (the CLI shows it as its flag).

Warnings that do not stop the work (more samples than asked, clipped pixels, ignored options)
are :class:`PacamWarning`: the CLI prints each as one ``note:`` line.
"""

from __future__ import annotations

import os
import warnings

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


def available_bytes() -> int:
    """Memory the process can still use: MemAvailable from /proc/meminfo, else physical RAM."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB"


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
            f"{what} needs about {_gib(nbytes)} of memory, and {_gib(free)} is available; "
            f"reduce {flags}"
        )


def check_count(what: str, count: float, limit: int, flag: str, hint: str = "") -> None:
    """Refuse ``count`` units of work above ``limit``, naming the parameter (``flag``) that
    raises it."""
    if count > limit:
        raise ParameterError(
            f"{what}: {count:.4g}, above the limit of {limit} ({flag} raises it){hint}"
        )
