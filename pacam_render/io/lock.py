"""One writer per output folder: a second run into the same folder is refused at its start.

:func:`output_lock` holds an ``fcntl`` lock on ``DIR/.pacam.lock``. The kernel drops it when
the process ends, however it ends, so a crash never leaves a stale lock. The lock is re-entrant
within a process (the CLI holds it over a whole command and :func:`render_capture` takes it
again for its checkpoints).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from ..errors import ParameterError

LOCK_NAME = ".pacam.lock"
_held: dict[Path, int] = {}


@contextlib.contextmanager
def output_lock(folder: str | os.PathLike, flag: str = "`out`") -> Iterator[Path]:
    """Hold the folder's lock for the ``with`` block.

    Parameters
    ----------
    folder : path-like
        The output folder (created if missing).
    flag : str, optional
        How the user named the folder, for the message.

    Yields
    ------
    pathlib.Path
        The lock file.

    Raises
    ------
    ParameterError
        If another process holds the lock.
    """
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    path = (d / LOCK_NAME).resolve()
    if path in _held:
        _held[path] += 1
        try:
            yield path
        finally:
            _held[path] -= 1
        return
    fd = _acquire(path, flag, d)
    _held[path] = 1
    try:
        yield path
    finally:
        del _held[path]
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # while still locked, so no one locks the old file after us
        os.close(fd)


def check_unlocked(folder: str | os.PathLike, flag: str = "`out`") -> None:
    """Refuse a folder whose lock another process holds (a running render's ``out``), without
    taking it: for commands that write a few files and hold no lock of their own.

    Raises
    ------
    ParameterError
        If another process holds the folder's lock.
    """
    d = Path(folder)
    path = (d / LOCK_NAME).resolve()
    if path in _held or not path.is_file():
        return
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:  # its holder just finished
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        raise _busy(fd, flag, d) from None
    finally:
        os.close(fd)


def _busy(fd: int, flag: str, shown: Path) -> ParameterError:
    """The refusal of a folder whose lock file ``fd`` another process holds."""
    holder = os.read(fd, 64).decode(errors="replace").strip() or "another process"
    return ParameterError(
        f"{flag} {shown} is in use by another pacam run ({holder}); wait for it to finish or "
        "choose another folder"
    )


def _acquire(path: Path, flag: str, shown: Path) -> int:
    """Lock ``path``; retry if the file we locked was unlinked by a finishing holder."""
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            err = _busy(fd, flag, shown)
            os.close(fd)
            raise err from None
        try:
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"pid {os.getpid()}".encode())
            return fd
        os.close(fd)
