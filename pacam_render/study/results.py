"""A study's results folder: ``results.csv`` (one row per point) and ``study.json`` (which
study the rows belong to).

The CSV is rewritten whole, to a temporary file renamed into place, each time a task finishes,
so it is never half-written and holds every finished point even after Ctrl-C or a crash. A
re-run of the same study skips the points whose status is ``ok``; failed points run again.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from ..errors import ParameterError
from ..io.outputs import write_json, write_text
from .point import COLUMNS
from .spec import StudySpec

RESULTS, STUDY = "results.csv", "study.json"


class Results:
    """The rows of a study's folder, resumed from disk when they belong to the same study.

    Raises
    ------
    ParameterError
        If the folder holds results of another study (or of the same study with other
        settings) and ``force`` is false.
    """

    def __init__(self, out: Path, spec: StudySpec, force: bool = False):
        self.path, self.meta_path = out / RESULTS, out / STUDY
        self.rows: dict[int, dict] = {}
        self.resumed = 0
        meta = {"name": spec.name, "key": spec.key(), "points": len(spec.points)}
        if self.meta_path.exists() and not force:
            old = _read_json(self.meta_path)
            if old.get("key") != meta["key"]:
                raise ParameterError(
                    f"`out` {out} holds results of another study ({old.get('name')!r}, or the "
                    "same study with other settings); pass `force=True` to start afresh there, "
                    "or choose another `out`"
                )
            self.rows = _resumed_rows(self.path)
            self.resumed = len(self.done())
        elif self.path.exists() and not force:
            raise ParameterError(
                f"`out` {out} holds a {RESULTS} of unknown origin; pass `force=True`"
            )
        write_json(self.meta_path, {**meta, "source": spec.source}, force=True)
        if not self.rows:
            self._write()

    def done(self) -> set[int]:
        """Points finished with status ``ok``."""
        return {k for k, r in self.rows.items() if r.get("status") == "ok"}

    def add(self, rows: list[dict]) -> None:
        """Record finished rows (replacing earlier rows of the same points) and save."""
        for r in rows:
            self.rows[int(r["point"])] = r
        self._write()

    def ordered(self) -> list[dict]:
        return [self.rows[k] for k in sorted(self.rows)]

    def _write(self) -> None:
        buf = io.StringIO()
        writer = csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(self.ordered())
        write_text(self.path, buf.getvalue(), force=True)


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ParameterError(f"{path} is not readable JSON ({exc}); pass `force=True`") from None


def _resumed_rows(path: Path) -> dict[int, dict]:
    """The rows of an earlier run by point; refused if the file is not such a table."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            if path.stat().st_size and "point" not in (reader.fieldnames or []):
                raise KeyError("no 'point' column")
            rows = {int(r["point"]): r for r in reader}
    except FileNotFoundError:
        return {}
    except (KeyError, TypeError, ValueError) as exc:  # no point column, not an integer, binary
        raise ParameterError(
            f"{path} is unreadable ({type(exc).__name__}: {exc}); pass `force=True` to start afresh"
        ) from None
    if any(k < 0 for k in rows):
        raise ParameterError(f"{path} is unreadable (a negative point); pass `force=True`")
    return rows


def read_csv(path: Path) -> list[dict]:
    """The rows of a results CSV as strings; none if the file does not exist."""
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))
