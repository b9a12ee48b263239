"""``DIR/index.csv``: one row per sample, rewritten whole (a temporary file renamed into place)
each time a render finishes, so it is never half-written and holds every finished sample even
after Ctrl-C or a crash.

Columns: ``id`` (the sample's folder under ``samples/``), ``scene``, ``scene_seed`` (a family's
seed; empty for a listed scene), ``camera``, ``light_level`` (photons/px/ms), ``render_error``
(the capture's Monte Carlo sigma, its units), ``ratio_to_sensor`` (that sigma over the sensor's
noise), ``seconds`` (the render's, shared by its light levels), ``digest`` (of the sample's
arrays), ``key`` (of everything that determines it), ``status`` (``ok`` or ``failed``) and
``error`` (a failed sample's reason).
"""

from __future__ import annotations

import csv
from pathlib import Path

from ..errors import ParameterError
from ..io.outputs import csv_text, write_text

INDEX = "index.csv"
COLUMNS = ("id", "scene", "scene_seed", "camera", "light_level", "render_error",
           "ratio_to_sensor", "seconds", "digest", "key", "status", "error")  # fmt: skip


def scene_seed(scene: str) -> str:
    """A family scene's seed (``family:NAME:SEED``), or ``""``."""
    return scene.rsplit(":", 1)[1] if scene.startswith("family:") else ""


def row(sample, status: str, error: str = "", **values) -> dict:
    """An index row of ``sample`` (:class:`~.plan.PlannedSample`); ``values`` fill the numbers."""
    out = dict.fromkeys(COLUMNS, "")
    out.update(id=sample.id, scene=sample.scene, scene_seed=scene_seed(sample.scene),
               camera=sample.camera, light_level=sample.light_level, key=sample.key,
               status=status, error=error.replace("\n", " ")[:500])  # fmt: skip
    out.update(values)
    return out


def read_index(folder) -> list[dict]:
    """The rows of ``folder/index.csv`` as dicts of strings (empty when there is none)."""
    path = Path(folder) / INDEX
    if not path.is_file():
        return []
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ParameterError(f"{path} cannot be read as the dataset's index: {exc}") from None
    if rows and not {"id", "key", "status"} <= set(rows[0]):
        raise ParameterError(f"{path} is not a dataset's index (no id, key and status columns)")
    return rows


def write_index(folder, rows: list[dict]) -> Path:
    """Write ``rows`` (in :data:`COLUMNS` order) to ``folder/index.csv``, atomically."""
    ordered = [{k: r.get(k, "") for k in COLUMNS} for r in rows]
    if not ordered:
        return write_text(Path(folder) / INDEX, ",".join(COLUMNS) + "\n", force=True)
    return write_text(Path(folder) / INDEX, csv_text(ordered, "{:.6g}"), force=True)
