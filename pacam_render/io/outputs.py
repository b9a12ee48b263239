"""Safe output files: written to a temporary name in the same folder, then renamed, so a crash
never leaves a half-written result; an existing result is never replaced without ``force``."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from ..errors import ParameterError
from .lock import check_unlocked


def check_writable(path: str | os.PathLike, force: bool, flag: str = "") -> Path:
    """The path as a Path, or an error if it exists and ``force`` is not set, or if its folder
    cannot be created or written (:func:`writable_dir`)."""
    p = Path(path)
    name = f"{flag} {p}" if flag else str(p)
    if p.is_dir():
        raise ParameterError(f"{name} is a folder; give a file name")
    if p.exists() and not force:
        raise ParameterError(f"{name} already exists; pass `force=True` to overwrite it")
    writable_dir(p.parent, flag)
    return p


def writable_dir(path: str | os.PathLike, flag: str = "`out`", create: bool = True) -> Path:
    """Prove a folder writable with a probe file, or raise; create it if ``create``.

    Parameters
    ----------
    path : path-like
    flag : str, optional
        How the user named it, for the message.
    create : bool, optional
        Create the folder (and its parents). False: probe its nearest existing ancestor
        instead, and create nothing.

    Raises
    ------
    ParameterError
        If the path is a file, lies under a file, or cannot be created or written.
    """
    d = Path(path)
    if d.is_symlink() and not d.exists():  # else "File exists" from mkdir
        raise ParameterError(
            f"{flag} {d} is a link to {os.readlink(d)}, which does not exist; remove the link "
            "or create its target"
        )
    probe_in = d
    while not probe_in.exists() and probe_in.parent != probe_in:
        probe_in = probe_in.parent  # the nearest existing ancestor
    if probe_in.exists() and not probe_in.is_dir():
        where = "exists" if probe_in == d else f"lies under {probe_in}, which exists"
        raise ParameterError(f"{flag} {d} {where} and is not a folder")
    if create:
        probe_in = d
    try:
        if create:
            d.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".pacam-probe-", dir=probe_in)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ParameterError(f"{flag} {d} is not a writable folder ({exc.strerror})") from None
    return d


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


def prepare_out_dir(path: str | os.PathLike, force: bool, names=None) -> Path:
    """An output folder, proven writable (:func:`writable_dir`) but not created: the first
    result written creates it. Refused if it already holds files (or, given ``names``, any of
    the files the command writes, so that e.g. a PSF can go beside its capture), unless
    forced."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise ParameterError(f"`out` {d} exists and is not a folder")
    check_unlocked(d)  # a running render's folder
    held = [] if not d.is_dir() else [p.name for p in d.iterdir() if p.name != ".pacam.lock"]
    if names is not None:
        held = [n for n in held if n in set(names)]
    if held and not force:
        raise ParameterError(
            f"`out` {d} already holds results ({', '.join(sorted(held)[:3])}); pass "
            "`force=True` to overwrite them"
        )
    return writable_dir(d, create=False)


def csv_text(rows: list[dict], float_format: str | None = None) -> str:
    """Rows (dicts with the same keys, in order) as CSV text; floats through ``float_format``
    (e.g. ``"{:.6g}"``) if given."""
    import csv
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    for r in rows:
        if float_format is not None:
            r = {k: (float_format.format(v) if isinstance(v, float) else v) for k, v in r.items()}
        w.writerow(r)
    return buf.getvalue()


def save_figure(fig, path, dpi: int) -> Path:
    """Save a matplotlib figure as PNG through a temporary file (replacing ``path``), and
    close it."""
    import matplotlib.pyplot as plt

    try:
        return atomic_save(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png"), force=True)
    finally:
        plt.close(fig)
