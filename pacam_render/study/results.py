"""A study's results folder: ``results.csv`` (one row per point) and ``study.json`` (which
study the rows belong to).

The CSV is rewritten whole, to a temporary file renamed into place, each time a task finishes,
so it is never half-written and holds every finished point even after Ctrl-C or a crash. A
re-run of the same study skips the points whose status is ``ok``; failed points run again.

Each row records its ``point_key`` (:meth:`~.spec.StudySpec.point_keys`), a hash of everything
that determines it. A re-run with an edited spec keeps the rows whose key a point of the new
spec has (renumbered to that point), and sets the rest aside: the old ``results.csv`` is
first copied to ``results.before-KEY.csv`` (KEY: the old spec's). An ``images/`` folder, whose
files are named by render and point numbers, moves to ``images.before-KEY`` on any edit. A
:class:`~pacam_render.limits.PacamWarning` says how many rows were kept, how many points are
to run and how many rows were set aside, and where. A folder written before rows had keys is
resumed only by the same spec, as before.

Each row also records ``row_digest``, a hash of its other cells as written. A resumed row
whose digest does not match (edited by hand, or damaged), or an ``ok`` row whose PSNR, SSIM or
seconds do not read as finite numbers, is not taken as done: its point runs again, and a note
says how many rows and which points.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import warnings
from pathlib import Path

from ..errors import ParameterError
from ..io.outputs import write_json, write_text
from ..limits import PacamWarning
from .point import COLUMNS, LATE_COLUMNS
from .spec import StudySpec

RESULTS, STUDY = "results.csv", "study.json"


class Results:
    """The rows of a study's folder, resumed from disk: all of them for the same study, those
    whose ``point_key`` a point of ``spec`` has for an edited one (see the module docstring).

    Attributes
    ----------
    set_aside : int
        Rows of an earlier spec that no point of ``spec`` has, left in ``backup``.
    backup : pathlib.Path or None
        Where the old ``results.csv`` was copied before those rows were dropped.

    Raises
    ------
    ParameterError
        If the folder holds results without point keys (written before they were recorded) of
        another study, or of the same study with other settings, and ``force`` is false.
    """

    def __init__(self, out: Path, spec: StudySpec, force: bool = False):
        self.path, self.meta_path = out / RESULTS, out / STUDY
        self.rows: dict[int, dict] = {}
        self.resumed, self.set_aside, self.backup = 0, 0, None
        self.keys = spec.point_keys()
        meta = {"name": spec.name, "key": spec.key(), "points": len(spec.points)}
        if self.meta_path.exists() and not force:
            old = _read_json(self.meta_path)
            rows, keyed = _resumed_rows(self.path)
            rows = _intact_rows(out, rows)
            if keyed:
                self._by_key(out, rows, str(old.get("key")), meta["key"], len(spec.points))
            elif old.get("key") == meta["key"]:  # the same points in the same order: keys follow
                self.rows = {k: {**r, "point_key": self.keys.get(k, "")} for k, r in rows.items()}
            else:
                raise ParameterError(
                    f"`out` {out} holds results of another study ({old.get('name')!r}, or the "
                    "same study with other settings); pass `force=True` to start afresh there, "
                    "or choose another `out`"
                )
            self.rows = {k: {**r, "row_digest": row_digest(r)} for k, r in self.rows.items()}
            self.resumed = len(self.done())
        elif self.path.exists() and not force:
            raise ParameterError(
                f"`out` {out} holds a {RESULTS} of unknown origin; pass `force=True`"
            )
        self._write()  # first: a study.json never names a spec whose numbering the CSV lacks
        write_json(self.meta_path, {**meta, "source": spec.source}, force=True)

    def _by_key(self, out: Path, rows: dict, old_key: str, new_key: str, points: int) -> None:
        """Keep the rows whose key a point of the spec has, under its index. If the spec was
        edited: copy the old file aside first when a row is dropped, move ``images/`` aside
        (its files are named by render and point numbers, which an edit may change), and
        say so."""
        index = {point_key: k for k, point_key in self.keys.items()}
        kept = {index[r.get("point_key")]: r for r in rows.values() if r.get("point_key") in index}
        self.rows = {k: {**r, "point": k} for k, r in kept.items()}
        self.set_aside = len(rows) - len(kept)
        renumbered = any(int(r["point"]) != k for k, r in kept.items())
        if old_key == new_key and not self.set_aside and not renumbered:
            return  # the same study: nothing to say
        where = ""
        if self.set_aside:
            self.backup = _free_name(out, f"results.before-{old_key}", ".csv")
            write_text(self.backup, self.path.read_text(encoding="utf-8"))
            where = f" in {self.backup}"
        images = out / "images"
        if images.is_dir():
            moved = _free_name(out, f"images.before-{old_key}", "")
            os.replace(images, moved)
            where += f"; images/ moved to {moved}"
        done = len(self.done())
        warnings.warn(
            f"`out` {out} holds results of another spec: {done} points kept (their point_key "
            f"unchanged), {points - done} to run, {self.set_aside} old rows set aside{where} "
            "(`force=True` starts afresh)",
            PacamWarning,
            stacklevel=3,
        )

    def done(self) -> set[int]:
        """Points finished with status ``ok``."""
        return {k for k, r in self.rows.items() if r.get("status") == "ok"}

    def add(self, rows: list[dict]) -> None:
        """Record finished rows (replacing earlier rows of the same points) and save."""
        for r in rows:
            row = {**r, "point_key": self.keys.get(int(r["point"]), "")}
            self.rows[int(r["point"])] = {**row, "row_digest": row_digest(row)}
        self._write()

    def ordered(self) -> list[dict]:
        return [self.rows[k] for k in sorted(self.rows)]

    def _write(self) -> None:
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(self.ordered())
        write_text(self.path, buf.getvalue(), force=True)


def _intact_rows(out: Path, rows: dict[int, dict]) -> dict[int, dict]:
    """The rows that are what the study wrote (:func:`row_is_intact`); a note names the
    others, whose points run again."""
    bad = sorted(k for k, r in rows.items() if not row_is_intact(r))
    if bad:
        more = ", ..." if len(bad) > 10 else ""
        warnings.warn(
            f"`out` {out}: {len(bad)} row(s) of {RESULTS} are not what the study wrote (edited "
            f"or damaged: point(s) {', '.join(map(str, bad[:10]))}{more}); they run again",
            PacamWarning,
            stacklevel=4,
        )
    return {k: r for k, r in rows.items() if k not in bad}


def row_digest(row: dict) -> str:
    """16 hex digits of SHA-256 over the row's cells as the CSV writes them (str of each
    value, "" for None), every column but ``row_digest`` itself."""
    # an optics cell counts only when it holds a value: rows from before those columns match
    cols = [
        c for c in COLUMNS
        if c != "row_digest" and (c not in LATE_COLUMNS or row.get(c) not in (None, ""))
    ]  # fmt: skip
    cells = ["" if row.get(c) is None else str(row.get(c)) for c in cols]
    return hashlib.sha256(json.dumps(cells).encode()).hexdigest()[:16]


NUMBER_COLUMNS = ("psnr_db", "ssim", "render_s", "total_s")
"""Cells an ``ok`` row must hold as finite numbers."""


def row_is_intact(row: dict) -> bool:
    """The row is what the study wrote (its digest matches, where it has one), and an ``ok``
    row's numbers read as finite numbers."""
    if row.get("row_digest") and row["row_digest"] != row_digest(row):
        return False
    if row.get("status") != "ok":
        return True
    try:
        return all(
            math.isfinite(float(row[c])) for c in NUMBER_COLUMNS if row.get(c) not in (None, "")
        )
    except (TypeError, ValueError):
        return False


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ParameterError(f"{path} is not readable JSON ({exc}); pass `force=True`") from None


def _free_name(folder: Path, stem: str, suffix: str) -> Path:
    """``folder/stem+suffix``, or with ``-2``, ``-3``, ... added: a name nothing has."""
    path, n = folder / f"{stem}{suffix}", 1
    while path.exists():
        n += 1
        path = folder / f"{stem}-{n}{suffix}"
    return path


def _resumed_rows(path: Path) -> tuple[dict[int, dict], bool]:
    """The rows of an earlier run by point, and whether they carry point keys (a file
    without rows does: nothing is lost with it); refused if the file is not such a table."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            if path.stat().st_size and "point" not in (reader.fieldnames or []):
                raise KeyError("no 'point' column")
            rows = {int(r["point"]): r for r in reader}
            keyed = "point_key" in (reader.fieldnames or []) or not rows
    except FileNotFoundError:
        return {}, True
    except (KeyError, TypeError, ValueError) as exc:  # no point column, not an integer, binary
        raise ParameterError(
            f"{path} is unreadable ({type(exc).__name__}: {exc}); pass `force=True` to start afresh"
        ) from None
    if any(k < 0 for k in rows):
        raise ParameterError(f"{path} is unreadable (a negative point); pass `force=True`")
    return rows, keyed


def read_csv(path: Path) -> list[dict]:
    """The rows of a results CSV as strings; none if the file does not exist."""
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))
