"""The time steps of a capture's passes: where a moving scene's exposure is cut, how a pass's
samples are shared among the steps, and the random time each step takes in each pass.

A moving scene is split at the pattern boundaries, and each pattern window into m time steps,
so that nothing moves more than ``max_step_px`` between the ends of a step: m = ceil(v_max dt /
max_step_px), v_max the fastest image speed of any moving shape. In each pass, each step draws
one time uniformly within its window: the geometry is posed at that time (one BVH rebuild), and
every ray of the step takes that time and the window's weight (the sensor's
``time_window=(start, end, at)``). The step's image is then an unbiased estimate of the
window's, for held and continuous schedules alike, and the time steps add noise, which the
passes' spread measures (:mod:`.estimate`), instead of the midpoint rule's bias (first order in
the step for a sharp feature crossing a pixel edge). The passes draw their times
independently, so the error stays measurable; within a pass the times are stratified, one per
step.

A pass of N samples per pixel shares them among its steps in proportion to their duration,
each step a multiple of the sampler's smallest render (:mod:`~..render.samplers`) and at least
one of them. A pass of fewer such renders than steps joins each pattern's neighbouring steps
(:func:`merge_windows`, down to one step per pattern), so a low spp is honoured: the joined
steps draw their time over their whole span, which adds noise and no bias. That noise is
shared by every moving pixel, so a fixed capture whose sampler would join its steps much
coarser than independent samples would renders with those instead (:func:`fine_step_sampler`,
in :mod:`.direct`). Every step of every pass has its own seeds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..limits import DEFAULT_MAX_STEPS, check_count, note
from ..render.samplers import quantum
from ..scenes import fastest_image_speed_px_per_ms


@dataclass(frozen=True)
class Step:
    """One render of a moving scene: shutter window [t0, t1] ms and its samples per pixel."""

    pattern: int
    t0: float
    t1: float
    spp: int


def plan_windows(
    edges: np.ndarray,
    is_open: np.ndarray,
    speed_px_per_ms: float,
    max_step_px: float,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> list[tuple[int, float, float]]:
    """The time steps of a moving scene: (pattern, t0, t1) on the shutter's clock, ms.

    Parameters
    ----------
    edges : ndarray
        The n + 1 pattern boundaries on the shutter's clock, ms.
    is_open : ndarray of bool
        Whether each of the n pattern windows lets light in; closed windows get no steps.
    speed_px_per_ms : float
        The fastest image speed of any moving shape, px/ms.
    max_step_px : float
        The most image motion across one step, px.
    max_steps : int, optional
        The most steps allowed (``max_steps``).

    Returns
    -------
    list of tuple
        In time order: each open window [a, b] is cut into
        m = max(1, ceil(v_max (b - a) / max_step_px)) equal steps.

    Raises
    ------
    ParameterError
        If the plan needs more than ``max_steps`` steps (counted before any is built).
    """
    windows = [(k, a, b) for k, (a, b, o) in enumerate(zip(edges[:-1], edges[1:], is_open)) if o]
    counts = [speed_px_per_ms * (b - a) / max_step_px - 1e-9 for _, a, b in windows]
    check_count(
        "time steps of this capture (fastest image speed "
        f"{speed_px_per_ms:.4g} px/ms, max_step_px {max_step_px:g})",
        sum(_n_steps(c) for c in counts),
        max_steps,
        "max_steps",
        "; or raise max_step_px",
    )
    out = []
    for (k, a, b), c in zip(windows, counts):
        e = np.linspace(a, b, _n_steps(c) + 1)
        out += [(k, float(x), float(y)) for x, y in zip(e[:-1], e[1:])]
    return out


def share_spp(durations, spp: int, quantum: int = 1) -> list[int]:
    """Samples per pixel of each step: ``spp`` shared in proportion to ``durations``.

    Each step gets floor(spp d / D / q) q samples (D the total duration, q the ``quantum``), at
    least q; the quanta still to give go to the largest remainders. The total is ``spp``
    rounded up to q, or more where the minimum of q per step forces it.
    """
    dur = np.asarray(durations, float)
    units = -(-int(spp) // quantum)
    share = units * dur / dur.sum()
    n = np.maximum(1, np.floor(share)).astype(int)
    left = units - int(n.sum())
    if left > 0:  # largest remainders get the quanta still to give
        n[np.argsort(-(share - np.floor(share)), kind="stable")[:left]] += 1
    return [int(v) * quantum for v in n]


def merge_windows(windows: list, units: int) -> list:
    """At most ``units`` steps (never fewer than one per pattern): each pattern's consecutive
    windows joined into as many steps as its share of ``units``.

    A pass of fewer samples than steps honours its spp this way instead of giving every step
    the sampler's smallest render. A joined step is still unbiased, since its time is drawn
    over its whole span; it only adds noise (larger poses apart), which the passes measure.
    """
    if units >= len(windows):
        return windows
    by_pattern: dict[int, list] = {}
    for w in windows:
        by_pattern.setdefault(w[0], []).append(w)
    total = sum(b - a for _, a, b in windows)
    out = []
    for k, ws in by_pattern.items():
        share = units * sum(b - a for _, a, b in ws) / total
        cuts = np.linspace(0, len(ws), min(len(ws), max(1, int(share))) + 1).round().astype(int)
        out += [(k, ws[i][1], ws[j - 1][2]) for i, j in zip(cuts[:-1], cuts[1:])]
    return out


def fine_step_sampler(sampler: str, pass_spp: int, windows: list) -> str:
    """The sampler whose passes keep their time steps shortest: ``sampler``, unless a pass of
    ``pass_spp`` samples per pixel cannot give each of the ``windows`` (:func:`plan_windows`)
    that sampler's smallest render, so that :func:`merge_windows` joins them into steps of
    more than ``JOINED`` windows on average, and independent samples (renders of one sample per
    pixel) would give ``JOINED`` times as many steps or more; then ``independent``.

    Joined steps are unbiased, but their time noise is not a pixel's own: every moving pixel
    sees the same few poses, so it lies in a few image-wide patterns that a capture's 2 or 4
    passes measure with as few degrees of freedom. Measured on the train's window (280, 656,
    160, 16), normal mode, 512 spp in 2 passes: ldsampler's 64 joined steps of 1 px left two
    renders of other seeds at pooled chi^2 0.34-0.61 (6 pairs), where independent samples in
    all 126 steps of 0.5 px gave 0.91-1.08.
    """
    q = quantum(sampler)
    if q == 1 or pass_spp >= q * len(windows):
        return sampler
    joined = len(merge_windows(windows, -(-pass_spp // q)))
    finer = len(merge_windows(windows, pass_spp))
    return "independent" if finer >= JOINED * joined and finer > joined else sampler


JOINED = 1.6
"""How much finer independent samples must cut a pass's time (steps, x) before
:func:`fine_step_sampler` takes them: the measured harm is at steps of twice ``max_step_px``
(1.97 x on the train's window above); the regression cases train_normal and train_levin
(1.5 x) and psf_coded (1.1 x) keep the ldsampler they were blessed with."""


def plan_steps(
    edges: np.ndarray,
    is_open: np.ndarray,
    speed_px_per_ms: float,
    spec,
    max_steps: int = DEFAULT_MAX_STEPS,
    spp: int | None = None,
    quantum: int = 1,
) -> list[Step]:
    """:func:`plan_windows` with ``spec.max_step_px``, and :func:`share_spp` of ``spp``
    (default ``spec.spp``) samples among them."""
    windows = plan_windows(edges, is_open, speed_px_per_ms, spec.max_step_px, max_steps)
    shares = share_spp([b - a for _, a, b in windows], spec.spp if spp is None else spp, quantum)
    return [Step(k, a, b, n) for (k, a, b), n in zip(windows, shares)]


def _n_steps(count: float) -> float:
    """Steps for a window that the fastest point crosses in ``count`` step lengths."""
    return max(1, math.ceil(count)) if math.isfinite(count) else math.inf


def step_draws(seed: int, pass_index: int, step: int) -> tuple[int, float]:
    """The Mitsuba seed and the uniform time draw of one step of one pass."""
    words = np.random.SeedSequence([seed, pass_index, step]).generate_state(2, np.uint64)
    return int(words[0] >> np.uint64(33)), float(words[1] >> np.uint64(11)) * 2.0**-53


def step_time(t0: float, t1: float, u: float) -> float:
    """A time in [t0, t1] from a uniform draw ``u``, kept 8 float32 ulps from both ends, so
    that the sensor's float32 ray time falls in the step's own pattern (the interval loses
    a relative 1e-4 or less, which moves no estimate measurably)."""
    guard = 8 * float(np.spacing(np.float32(max(abs(t0), abs(t1), 1.0))))
    guard = min(guard, 0.25 * (t1 - t0))
    return t0 + guard + u * (t1 - t0 - 2 * guard)


@dataclass
class Exposure:
    """What one pass renders: the scene, its sensor and, for a moving scene, its time steps.

    ``windows`` is empty for a static pass (one render over the whole exposure, nothing
    moved); ``mid_ms`` is the shutter time of the paper's t = 0; ``quantum`` the sampler's
    smallest render, spp.
    """

    scene: Any
    sensor: Any
    animator: Any = None
    windows: list = field(default_factory=list)
    mid_ms: float = 0.0
    quantum: int = 1
    pixels: int = 1

    @property
    def moving(self) -> bool:
        return bool(self.windows)

    def pass_quantum(self) -> int:
        """The smallest pass, spp: one sampler quantum per step."""
        return self.quantum * max(1, len(self.windows))

    def steps(self, spp: int) -> list[Step]:
        """The steps of a pass of ``spp`` samples per pixel (one step for a static pass)."""
        if not self.moving:
            return [Step(0, 0.0, 0.0, max(self.quantum, -(-spp // self.quantum) * self.quantum))]
        windows = merge_windows(self.windows, -(-spp // self.quantum))
        shares = share_spp([b - a for _, a, b in windows], spp, self.quantum)
        return [Step(k, a, b, n) for (k, a, b), n in zip(windows, shares)]

    def steps_per_pass(self, spp: int) -> int:
        """How many renders a pass of ``spp`` samples per pixel takes."""
        return len(self.steps(spp)) if self.moving else 1


def plan_exposure(scene, sensor, desc, design, cam, spec, max_steps: int = DEFAULT_MAX_STEPS):
    """The :class:`Exposure` of a capture, and the fastest image speed (px/ms).

    A static scene, or the reference, is one render per pass (no windows, speed 0); a moving
    scene gets the time steps of :func:`plan_windows` at the fastest image speed of any of its
    shapes over the paper's t in [-T, T].
    """
    w, h = spec.image_size
    exp = Exposure(scene, sensor, quantum=quantum(spec.sampler), pixels=w * h)
    if desc.is_static or spec.mode == "reference":  # one render per pass, no geometry update
        if spec.per_pattern:
            note("per_pattern keeps nothing here: a static scene or the reference is one pass")
        return exp, 0.0
    exp.windows, speed = exposure_windows(desc, design, cam, spec, sensor.plan, max_steps)
    exp.animator, exp.mid_ms = desc.animator(scene), 0.5 * cam.exposure_ms
    return exp, speed


def exposure_windows(desc, design, cam, spec, aperture, max_steps: int = DEFAULT_MAX_STEPS):
    """A moving capture's time steps (:func:`plan_windows` over ``aperture``'s patterns, an
    :class:`~pacam_render.render.plan.AperturePlan`) and its fastest image speed, px/ms; no
    scene is loaded (the planner's cost model takes them before any render)."""

    exposure = cam.exposure_ms
    speed = fastest_image_speed_px_per_ms(desc, design, (-0.5 * exposure, 0.5 * exposure))
    edges, is_open = aperture.pattern_edges, aperture.is_open
    return plan_windows(edges, is_open, speed, spec.max_step_px, max_steps), speed
