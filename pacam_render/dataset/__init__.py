"""Datasets of coded captures with their ground truth (issue 57): a TOML spec of scenes x
cameras x light levels (:mod:`.spec`), planned and bounded before any work (:mod:`.plan`),
rendered on Dask, resumable by key (:mod:`.run`, :mod:`.sample`), indexed (:mod:`.index`),
described in a card (:mod:`.card`), and read back as numpy arrays (:mod:`.loader`).

``pacam dataset SPEC.toml --out DIR`` is the command line; ``docs/howto/dataset.md`` the guide.
"""

from .loader import Dataset, Sample, open_dataset
from .plan import DatasetPlan, break_even_cameras, plan_dataset
from .run import RunSummary, run_dataset
from .spec import DatasetSpec, load_spec, parse_spec

__all__ = [
    "Dataset",
    "DatasetPlan",
    "DatasetSpec",
    "RunSummary",
    "Sample",
    "break_even_cameras",
    "load_spec",
    "open_dataset",
    "parse_spec",
    "plan_dataset",
    "run_dataset",
]
