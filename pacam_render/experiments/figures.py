"""The shared set-up of the paper's simulation figures (Section 3), for :mod:`.reproduce`.

scikit-image photographs instead of the paper's 30 Flickr images
(:data:`pacam_render.experiments.IMAGE_NAMES`), Wiener deconvolution, Gaussian noise sigma = 0.01
on [0, 1] images unless the photon budget matters, exposure 2T = 45 ms, r = 2 px unless swept.
Every curve is computed twice where it matters: with the paper's continuous model (Eq. 14) and
with the 16 held patterns the camera really shows (:data:`MODELS`). Here: :class:`Figure`, the
sweep sizes, the coded kernels, and the photon budgets of Figs. 7 and 8.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.outputs import save_figure
from ..model import paper
from ..psf import analytic as P
from ..sensor.model import SensorModel
from . import simulate as E

T_MS = 0.5 * paper.EXPOSURE_MS
SIGMA = 0.01
R_PX = 2.0
MODELS = {"Eq. 14 (continuous)": "continuous", "16 patterns (camera)": "discrete"}


@dataclass
class Figure:
    """One reproduced figure: its rows, its plot and its summary."""

    name: str
    rows: list[dict]
    plot: Callable[[Path], None]
    summary: str
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)


def sweep_scale(quick: bool) -> dict:
    return (
        {"images": 4, "speeds": 8, "radii": 7, "depths": 9}
        if quick
        else {"images": None, "speeds": 20, "radii": 14, "depths": 21}
    )


def coded_kernel(model: str, s: float, a: float, r: float, n: int = paper.N_PATTERNS) -> np.ndarray:
    if model == "continuous":
        return P.coded_psf(s, a, r, T_MS)
    return P.discrete_coded_psf(s, a, r, T_MS, n)


def pad_for(kernels: list[np.ndarray]) -> int:
    return max(max(k.shape) for k in kernels) // 2 + 1


def mean_sem(v: np.ndarray) -> tuple[float, float]:
    return E.summarise(v)


# --- photon budgets -----------------------------------------------------------------------------
F_MIN = paper.F_MIN
SHORT_MS = paper.SHORT_EXPOSURE_MS
EXPOSURE_MS = paper.EXPOSURE_MS


def f_number_for(a_i: float, r_px: float) -> float:
    """The F-number that gives a_i with defocus r (Eq. 18): N = N_min (1 + a_i T^2 / 4r)."""
    return F_MIN * (1.0 + a_i * T_MS**2 / (4.0 * r_px))


def light(f_number: float, exposure_ms: float) -> float:
    """Collected light relative to F2.8 for 1 ms (open area x time)."""
    return (F_MIN / f_number) ** 2 * exposure_ms


def paper_noise(sigma: float) -> E.NoiseFn:
    """The paper's Gaussian noise through the ``paper`` sensor preset (read noise only)."""

    model = SensorModel.from_preset("paper", sigma=float(sigma))
    return E.sensor_noise(model, model.full_well_e, EXPOSURE_MS)


def save_fig(fig, path: Path) -> None:

    fig.tight_layout()
    save_figure(fig, path, 110)
