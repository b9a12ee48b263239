"""Safe output files: written to a temporary name in the same folder, then renamed, so a crash
never leaves a half-written result; an existing result is never replaced without ``force``."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import ParameterError


def check_writable(path: str | os.PathLike, force: bool) -> Path:
    """The path as a Path, or an error if it exists and ``force`` is not set."""
    p = Path(path)
    if p.exists() and not force:
        raise ParameterError(f"{p} already exists; pass --force (force=True) to overwrite it")
    p.parent.mkdir(parents=True, exist_ok=True)
    return p


def _umask() -> int:
    """The process's umask (reading it means setting it: set it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_save(path: str | os.PathLike, save: Callable[[str], None], force: bool = False) -> Path:
    """Call ``save(tmp_path)``, then rename the temporary file onto ``path``."""
    p = check_writable(path, force)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=p.suffix or ".tmp", dir=p.parent)
    os.close(fd)
    try:
        save(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; a result gets the umask's mode
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def write_text(path, text: str, force: bool = False) -> Path:
    def save(tmp: str) -> None:
        Path(tmp).write_text(text, encoding="utf-8")

    return atomic_save(path, save, force)


def write_json(path, obj, force: bool = False) -> Path:
    return write_text(path, json.dumps(obj, indent=2, sort_keys=True, default=float) + "\n", force)


def prepare_out_dir(path: str | os.PathLike, force: bool) -> Path:
    """An output folder: created if missing; refused if it already holds files, unless forced."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise ParameterError(f"--out {d} exists and is not a folder")
    if d.is_dir() and any(d.iterdir()) and not force:
        raise ParameterError(f"--out {d} already holds results; pass --force to overwrite them")
    d.mkdir(parents=True, exist_ok=True)
    return d
