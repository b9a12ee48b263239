"""Reading a dataset: :func:`open_dataset` gives its samples as numpy arrays with their records,
with no deep-learning dependency (``docs/howto/dataset.md`` wraps it in a PyTorch ``Dataset``
in ten lines).

Arrays are float32, as written: ``capture`` (the noise-free capture, its units: radiance x
open area / full aperture x exposure / 45 ms), ``noisy`` (through the sensor, the same units),
``raw`` (the sensor's DN, one mosaic channel), ``sharp``, ``depth`` (mm), ``velocity`` (px/ms,
x and y), ``object_id``, and ``psf`` (the capture's analytic PSF; None for a mode without one).
Images are (H, W, 3), or (H, W) for grey captures and one-channel layers.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..io.arrays import read_json
from ..io.exr import read_exr
from .index import INDEX, read_index
from .sample import SAMPLE_JSON, SAMPLES, layers_digest

LAYERS = ("capture", "noisy", "raw", "sharp", "depth", "velocity", "object_id")
"""The layers of capture.exr a :class:`Sample` holds."""


@dataclass
class Sample:
    """One sample's arrays (module docstring), its index ``row`` and its ``record`` (the
    capture's capture.json, with ``sample`` from sample.json and ``psf`` from psf.json)."""

    id: str
    capture: np.ndarray
    noisy: np.ndarray
    raw: np.ndarray
    sharp: np.ndarray
    depth: np.ndarray
    velocity: np.ndarray
    object_id: np.ndarray
    psf: np.ndarray | None
    record: dict
    row: dict


class Dataset:
    """A dataset folder's samples, in index order; by default only those whose status is
    ``ok`` (``status=None``: every row, a failed one raising when read).

    Examples
    --------
    >>> ds = open_dataset("out/ds")  # doctest: +SKIP
    >>> len(ds), ds[0].noisy.shape  # doctest: +SKIP
    (4, (24, 32, 3))
    """

    def __init__(self, folder, status: str | None = "ok"):
        self.folder = Path(folder)
        if not (self.folder / INDEX).is_file():
            raise ParameterError(f"{self.folder} is not a dataset: it has no {INDEX}")
        rows = read_index(self.folder)
        self.rows = [r for r in rows if status is None or r["status"] == status]

    def __len__(self) -> int:
        return len(self.rows)

    def __getitem__(self, i: int) -> Sample:
        if not -len(self) <= i < len(self):
            raise IndexError(f"sample {i} of a dataset of {len(self)}")
        return load_sample(self.folder, self.rows[i])

    def __iter__(self):
        for i in range(len(self)):
            yield self[i]

    @property
    def ids(self) -> list[str]:
        return [r["id"] for r in self.rows]


def open_dataset(folder, status: str | None = "ok") -> Dataset:
    """The dataset in ``folder`` (``pacam dataset --out``): a :class:`Dataset` of its samples
    with ``status`` (``ok`` by default; None: all).

    Raises
    ------
    ParameterError
        If the folder holds no index.csv.
    """
    return Dataset(folder, status)


def load_sample(folder, row: dict) -> Sample:
    """One sample's arrays and records, read from ``folder/samples/<id>``.

    Raises
    ------
    ParameterError
        If the sample did not render (``status`` not ok), or its folder is not the row's.
    """
    where = Path(folder) / SAMPLES / row["id"]
    if row["status"] != "ok":
        raise ParameterError(f"sample {row['id']} failed: {row.get('error', '')}")
    meta = read_json(where / SAMPLE_JSON, "the sample's")
    if meta.get("key") != row["key"]:
        raise ParameterError(
            f"{where} holds another sample (key {meta.get('key')} != {row['key']})"
        )
    layers = read_exr(where / "capture.exr")
    record = read_json(where / "capture.json", "the capture's")
    record["sample"] = meta
    psf = None
    if (where / "psf_analytic.exr").is_file():
        psf = read_exr(where / "psf_analytic.exr")["psf"]
        record["psf"] = read_json(where / "psf.json", "the PSF's")
    if layers_digest(layers, psf) != meta.get("digest"):  # an edited or damaged file
        raise ParameterError(
            f"{where}: its arrays' digest is not the one sample.json recorded when it was written "
            f"({meta.get('digest')}): a file was edited or damaged; render it again"
        )
    missing = [name for name in LAYERS if name not in layers]
    if missing:
        raise ParameterError(f"{where / 'capture.exr'} has no layer {missing[0]!r}")
    arrays = {name: layers[name] for name in LAYERS}
    return Sample(id=row["id"], psf=psf, record=record, row=row, **arrays)
