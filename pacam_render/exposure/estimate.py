"""The Monte Carlo error of a capture, measured from its independent passes.

A capture is the mean of independent passes. Each pass is an unbiased estimate of the whole
exposure: it has its own seeds, and, in a moving scene, its own random times within the time
steps (:mod:`pacam_render.exposure.direct`). The spread of the passes therefore measures the
render's error, whatever the sampler. A stratified or low-discrepancy sampler has no per-sample
variance that would say it. Passes come in groups of equal size: the two pilot passes of a capture
rendered to a noise target, then the main passes. For a group g of n_g passes of N_g samples per
pixel each, with per-pixel sample variance v_g, and N the total samples per pixel:

    mean = sum_g N_g sum_p I_gp / N,     Var(mean) = sum_g N_g^2 n_g v_g / N^2,

which is unbiased for any sampler, because every pass of a group has the same distribution.
``mc_sigma`` is the square root of Var(mean). It is given per pixel, and as the root mean square
over the window or an object, in the capture's own units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..errors import ParameterError, check_positive


@dataclass
class PassGroup:
    """Passes of ``spp`` samples per pixel each: their count, sum and sum of squares."""

    spp: int
    n: int = 0
    s1: np.ndarray | float = 0.0
    s2: np.ndarray | float = 0.0

    def add(self, image: np.ndarray) -> None:
        self.n += 1
        self.s1 = self.s1 + image
        self.s2 = self.s2 + image * image

    def variance(self) -> np.ndarray:
        """Per-pixel sample variance of one pass (n - 1 degrees of freedom); needs n >= 2."""
        if self.n < 2:
            raise ValueError("a pass group needs two passes for its variance")
        return np.maximum(self.s2 - self.s1 * self.s1 / self.n, 0.0) / (self.n - 1)


@dataclass
class PassStats:
    """A capture's passes, by group: the mean image and its per-pixel Monte Carlo variance."""

    groups: list[PassGroup] = field(default_factory=list)
    patterns: dict[int, np.ndarray] = field(default_factory=dict)
    """Per-pattern images, each pass's weighted by its samples (divide by :attr:`spp`)."""

    @property
    def spp(self) -> int:
        """Samples per pixel over every pass."""
        return sum(g.spp * g.n for g in self.groups)

    @property
    def n_passes(self) -> int:
        return sum(g.n for g in self.groups)

    def add(self, group: int, image: np.ndarray, patterns: dict | None = None) -> None:
        """One finished pass of group ``group`` (its per-pattern images in ``patterns``)."""
        g = self.groups[group]
        g.add(image)
        for k, img in (patterns or {}).items():
            self.patterns[k] = self.patterns.get(k, 0.0) + g.spp * img

    def mean(self) -> np.ndarray:
        """The capture: every pass weighted by its samples."""
        return sum(g.spp * g.s1 for g in self.groups if g.n) / self.spp

    def pattern_means(self) -> dict[int, np.ndarray]:
        return {k: v / self.spp for k, v in self.patterns.items()}

    def variance(self) -> np.ndarray:
        """Per-pixel variance of :meth:`mean` (the module docstring's Var(mean))."""
        total = self.spp
        return sum(g.spp**2 * g.n * self._pass_variance(g) for g in self.groups if g.n) / total**2

    def _pass_variance(self, g: PassGroup) -> np.ndarray:
        """One pass's variance; for a group of one pass (a checkpoint after the first main pass)
        that of a group of two or more, scaled by spp (a pass's variance goes as 1/spp)."""
        if g.n >= 2:
            return g.variance()
        known = [h for h in self.groups if h.n >= 2]
        if not known:
            raise ValueError("no pass group has two passes: the variance is not known yet")
        h = max(known, key=lambda h: h.spp * h.n)
        return h.variance() * (h.spp / g.spp)

    def sigma_px(self) -> np.ndarray:
        """Per-pixel Monte Carlo sigma of the capture, its own units."""
        return np.sqrt(self.variance())

    def ready(self) -> bool:
        """Whether every group with passes has two, so that the variance is known."""
        return bool(self.groups) and all(g.n >= 2 or g.n == 0 for g in self.groups)


def rms(variance: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Root mean square sigma from a per-pixel variance (H, W[, C]) over ``mask`` (H, W)."""
    v = variance if mask is None else variance[mask]
    return float(np.sqrt(np.mean(v))) if v.size else float("nan")


def error_summary(stats: PassStats, objects: dict | None, ids: np.ndarray | None) -> dict:
    """``mc_sigma`` over the window and per object (shape id to sigma), the capture's units."""
    var = stats.variance()
    out = {"mc_sigma": rms(var), "passes": stats.n_passes, "spp": stats.spp}
    out["pass_spp"] = [g.spp for g in stats.groups for _ in range(g.n)]
    if objects and ids is not None:
        out["mc_sigma_by_object"] = {
            name: rms(var, ids == int(key))
            for key, name in objects.items()
            if (ids == int(key)).any()
        }
    return out


class NoiseTarget(Protocol):
    """How far to render: the Monte Carlo sigma (RMS over the window, capture units) to reach,
    from what the pilot passes show (their mean image and the capture's record)."""

    def sigma(self, mean_image: np.ndarray, record) -> float: ...

    def to_json(self) -> dict: ...


@dataclass(frozen=True)
class AbsoluteTarget:
    """A Monte Carlo sigma in the capture's own units (``noise_target``)."""

    sigma_units: float

    def __post_init__(self) -> None:
        check_positive("noise_target", self.sigma_units, "(the capture's units)")

    def sigma(self, mean_image: np.ndarray, record) -> float:
        return self.sigma_units

    def to_json(self) -> dict:
        return {"kind": "absolute", "sigma": self.sigma_units}


PILOT_PASSES = 2
"""Pilot passes of a capture rendered to a noise target: the fewest that measure an error."""
MAIN_PASSES = 4
"""The passes that the rest of the predicted samples are split into; the capture stops after
any of them (from the second) once the target is met, and adds more if it is not."""
MARGIN = 1.1
"""The samples predicted from the pilot are raised by this factor: the pilot's sigma is itself an
estimate, and stopping early costs less than one more pass."""


def main_pass_spp(pilot: PassStats, sigma_target: float, quantum: int, max_spp: int) -> int:
    """Samples per pixel of each main pass, from the pilot's error (sigma^2 ~ 1 / spp).

    Parameters
    ----------
    pilot : PassStats
        The pilot passes (:data:`PILOT_PASSES`), already rendered.
    sigma_target : float
        The Monte Carlo sigma to reach, the capture's units.
    quantum : int
        The pass size's multiple (the sampler's and the steps' smallest pass).
    max_spp : int
        The most samples per pixel the capture may take in all.

    Returns
    -------
    int
        A multiple of ``quantum``, at least ``quantum``; 0 when the pilot already meets the
        target or leaves no samples to spend.
    """
    sigma = rms(pilot.variance())
    if sigma <= sigma_target:
        return 0
    need = pilot.spp * (sigma / sigma_target) ** 2 * MARGIN - pilot.spp
    room = max_spp - pilot.spp  # two main passes at least, for their spread
    per = min(quantum * math.ceil(need / MAIN_PASSES / quantum), quantum * (room // (2 * quantum)))
    return max(per, 0)


def spp_to_target(stats: PassStats, sigma_target: float) -> float:
    """Samples per pixel at which the capture's Monte Carlo sigma meets ``sigma_target``, from
    the passes so far and sigma^2 ~ 1 / spp, without :data:`MARGIN`: the least the target
    takes (a moving scene's pose noise, which larger passes do not lower, only adds to it).

    Parameters
    ----------
    stats : PassStats
        The passes rendered so far (the pilot), two or more.
    sigma_target : float
        The Monte Carlo sigma to reach, the capture's units, > 0.

    Returns
    -------
    float
        Samples per pixel in all, the passes so far included.
    """
    return stats.spp * (rms(stats.variance()) / sigma_target) ** 2


def pass_variance_fit(stats: PassStats) -> tuple[float, float]:
    """(a, b) of one pass's variance, a + b / spp (mean over the window), fitted to the groups
    that have two passes or more.

    A pass of a moving scene draws one time per step for all its samples, so its error has a
    part that more samples per pass do not reduce (``a``: the poses) beside the sampling part
    (``b / spp``). Least squares in 1 / spp; with one group, or a fit that would make a part
    negative, ``a`` is 0 (all sampling) or ``b`` is 0 (all floor), whichever fits.
    """
    pts = [(1.0 / g.spp, float(np.mean(g.variance()))) for g in stats.groups if g.n >= 2]
    if not pts:
        raise ValueError("no pass group has two passes: the variance is not known yet")
    x, v = np.array(pts).T
    if len(pts) >= 2 and np.ptp(x) > 0:
        b, a = np.polyfit(x, v, 1)
        if a >= 0 and b >= 0:
            return float(a), float(b)
    sampling = float(np.sum(x * v) / np.sum(x * x))  # v = b x through the origin
    floor = float(np.mean(v))  # v = a
    if np.sum((v - sampling * x) ** 2) <= np.sum((v - floor) ** 2):
        return 0.0, sampling
    return floor, 0.0


def passes_to_target(
    stats: PassStats, fit: tuple[float, float], spp: int, sigma_target: float, most: int
) -> int | None:
    """How many more passes of ``spp`` samples bring the window's Monte Carlo sigma to
    ``sigma_target`` (with :data:`MARGIN` on the variance), by the module docstring's Var(mean)
    and the per-pass variance ``fit`` (:func:`pass_variance_fit`); None if ``most`` do not."""
    known = sum(g.spp**2 * g.n * float(np.mean(var)) for g, var in _group_vars(stats))
    total, v = stats.spp, fit[0] + fit[1] / spp
    goal = sigma_target**2 / MARGIN
    # (known + n spp^2 v) <= goal (total + n spp)^2: the larger root of A n^2 + B n + C = 0
    a, b, c = goal * spp**2, 2 * goal * total * spp - spp**2 * v, goal * total**2 - known
    n = max(1, math.ceil((-b + math.sqrt(max(b * b - 4 * a * c, 0.0))) / (2 * a) - 1e-9))
    return n if n <= most else None


def _group_vars(stats: PassStats) -> list[tuple[PassGroup, np.ndarray]]:
    return [(g, stats._pass_variance(g)) for g in stats.groups if g.n]


def check_passes(passes: int) -> int:
    """``passes``: an integer >= 2 (two measure an error)."""
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 2:
        raise ParameterError(
            f"passes must be an integer >= 2 (their spread measures the error), got {passes!r}"
        )
    return int(passes)
