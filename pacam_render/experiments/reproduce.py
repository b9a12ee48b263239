"""``pacam reproduce``: the paper's simulation figures (Figs. 6-9) and the train scene, each as
CSV, PNG and a Markdown summary that sets the paper's claim beside our numbers.

Each figure has its module (:mod:`.fig6`, :mod:`.fig7`, :mod:`.fig8`, :mod:`.fig9`,
:mod:`.fig_train`) on the shared set-up of :mod:`.figures`; this one runs them on the study
engine and writes their files.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from ..errors import ParameterError
from ..io.outputs import csv_text, write_text
from ..study.engine import run_tasks
from .fig6 import fig6
from .fig7 import fig7
from .fig8 import fig8
from .fig9 import fig9
from .fig_train import fig_train
from .figures import Figure

FIGURES: dict[str, Callable[[bool, int], Figure]] = {
    "fig6": fig6,
    "fig7": fig7,
    "fig8": fig8,
    "fig9": fig9,
    "train": fig_train,
}


def run(
    names: list[str],
    out: Path,
    quick: bool,
    force: bool,
    seed: int = 0,
    workers: int = 0,
    scheduler: str | None = None,
) -> list[Figure]:
    """Compute and write each figure: NAME.csv, NAME.png, NAME.md in ``out``.

    Each figure is one task of :func:`compute_figure` on the study engine
    (:func:`~pacam_render.study.engine.run_tasks`: ``workers`` processes of a LocalCluster,
    0 for serial, or an existing Dask ``scheduler``); files are written here as each ends.
    """
    import matplotlib

    matplotlib.use("Agg")
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ParameterError(f"unknown figure {unknown}; valid: {', '.join(FIGURES)}, all")
    for n in names:  # refuse before computing anything
        for ext in ("csv", "png", "md"):
            if (out / f"{n}.{ext}").exists() and not force:
                raise ParameterError(
                    f"{out / f'{n}.{ext}'} exists; pass `force=True` to overwrite it"
                )
    done: dict[str, Figure] = {}

    def write(task, fig) -> None:
        if isinstance(fig, BaseException):
            raise fig
        write_text(out / f"{fig.name}.csv", csv_text(fig.rows), force=True)
        fig.plot(out / f"{fig.name}.png")
        stamp = f"\n\nComputed in {fig.seconds:.1f} s ({'quick' if quick else 'full'} run).\n"
        write_text(out / f"{fig.name}.md", fig.summary + stamp, force=True)
        done[fig.name] = fig

    run_tasks(compute_figure, [(n, quick, seed) for n in names], write, workers, scheduler)
    return [done[n] for n in names]


def compute_figure(task) -> Figure:
    """Figure ``name`` computed (a task: (name, quick, seed)), with its time in ``seconds``."""
    import matplotlib

    matplotlib.use("Agg")
    name, quick, seed = task
    t0 = time.perf_counter()
    fig = FIGURES[name](quick, seed)
    fig.seconds = time.perf_counter() - t0
    return fig
