"""Integrating a capture over its exposure: independent passes, each over the time steps of a
moving scene, until a sample budget or a noise target is met.

Time steps. A static scene is one render per pass: each ray's time selects the pattern in the
sensor, so there is no loop and no geometry update. A moving scene is split at the pattern
boundaries, and each pattern window into m time steps, so that nothing moves more than
``max_step_px`` between the ends of a step: m = ceil(v_max dt / max_step_px), v_max the fastest
image speed of any moving shape. In each pass, each step draws one time uniformly within its
window: the geometry is posed at that time (one BVH rebuild), and every ray of the step takes
that time and the window's weight (the sensor's ``time_window=(start, end, at)``). The
step's image is then an unbiased estimate of the window's, for held and continuous schedules
alike, and the time steps add noise, which the passes' spread measures
(:mod:`.estimate`), instead of the midpoint rule's bias (second order in the step). The passes
draw their times independently, so the error stays measurable; within a pass the times are
stratified, one per step.

Samples. A pass of N samples per pixel shares them among its steps in proportion to their
duration, each step a multiple of the sampler's smallest render (:mod:`~..render.samplers`)
and at least one of them; a pass therefore has at least that many samples per step. Every
step and every pass has its own seeds, so a stopped capture resumes from the work on disk and
gives the same image as an uninterrupted run.

Budget or target. Without a target a capture is ``passes`` passes of spp / passes samples.
With a target (:class:`~.estimate.NoiseTarget`), two pilot passes of the smallest size measure
the error, the samples the target needs are predicted from them (sigma^2 ~ 1 / N), and the
rest is rendered as :data:`~.estimate.MAIN_PASSES` equal passes; the capture stops after any
of them once its Monte Carlo sigma meets the target, adds passes while it does not, and stops
with a note at the sample limit.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..limits import DEFAULT_MAX_STEPS, check_count
from .estimate import (
    MAIN_PASSES,
    PILOT_PASSES,
    PassGroup,
    PassStats,
    main_pass_spp,
    rms,
)


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
        shares = share_spp([b - a for _, a, b in self.windows], spp, self.quantum)
        return [Step(k, a, b, n) for (k, a, b), n in zip(self.windows, shares)]


@dataclass
class Schedule:
    """The passes of a capture: their groups (spp each, count), and how many more to render.

    ``phase`` is ``fixed`` (a set number of passes), ``pilot`` or ``main`` (rendering to a
    target). JSON-able as is, for the checkpoint.
    """

    groups: list[list[int]]
    phase: str
    planned: int
    target_sigma: float | None = None
    met: bool | None = None
    max_spp: int = 0

    @property
    def done_passes(self) -> int:
        return sum(n for _, n in self.groups)

    @property
    def spp(self) -> int:
        return sum(s * n for s, n in self.groups)

    @property
    def planned_spp(self) -> int:
        """Samples per pixel once the planned passes are done (a targeted capture may stop
        sooner, or add passes)."""
        return self.spp + (self.planned - self.done_passes) * self.groups[-1][0]

    def next_pass(self) -> tuple[int, int] | None:
        """(group index, spp) of the next pass, or None when the capture is finished."""
        if self.done_passes >= self.planned:
            return None
        return len(self.groups) - 1, self.groups[-1][0]


def fixed_schedule(spec, exp: Exposure) -> Schedule:
    """``spec.passes`` passes of spp / passes samples (each at least the smallest pass)."""
    per = -(-spec.spp // spec.passes)
    spp = sum(s.spp for s in exp.steps(per))
    return Schedule(groups=[[spp, 0]], phase="fixed", planned=spec.passes)


def pilot_schedule(exp: Exposure, max_spp: int) -> Schedule:
    """Two pilot passes of the smallest size; :func:`advance` plans the rest."""
    spp = sum(s.spp for s in exp.steps(exp.pass_quantum()))
    return Schedule(groups=[[spp, 0]], phase="pilot", planned=PILOT_PASSES, max_spp=max_spp)


def advance(sched: Schedule, stats: PassStats, exp: Exposure, target, record) -> None:
    """After a pass of a targeted capture: set the target after the pilot and plan the main
    passes; then stop once the target is met (from the main group's second pass on), or add a
    pass while it is not and ``max_spp`` leaves room."""
    if sched.phase == "fixed" or (sched.phase == "pilot" and sched.done_passes < sched.planned):
        return
    if sched.phase == "pilot":
        sched.target_sigma = float(target.sigma(stats.mean(), record))
        sched.met = rms(stats.variance()) <= sched.target_sigma
        per = main_pass_spp(stats, sched.target_sigma, exp.pass_quantum(), sched.max_spp)
        if per and not sched.met:
            per = sum(s.spp for s in exp.steps(per))
            sched.groups.append([per, 0])
            stats.groups.append(PassGroup(spp=per))
            fits = (sched.max_spp - sched.spp) // per  # main_pass_spp leaves room for 2
            sched.phase, sched.planned = "main", sched.done_passes + min(MAIN_PASSES, fits)
        return
    if sched.groups[-1][1] < 2:
        return
    sched.met = rms(stats.variance()) <= sched.target_sigma
    if sched.met:
        sched.planned = sched.done_passes
    elif sched.done_passes >= sched.planned and sched.spp + sched.groups[-1][0] <= sched.max_spp:
        sched.planned += 1


def group_stats(sched: Schedule, arrays: dict) -> PassStats:
    """The :class:`PassStats` of a schedule, from checkpointed arrays (or empty)."""
    stats = PassStats()
    for g, (spp, n) in enumerate(sched.groups):
        s1 = arrays.get(f"s1_{g}", 0.0)
        s2 = arrays.get(f"s2_{g}", 0.0)
        stats.groups.append(PassGroup(spp=spp, n=n, s1=s1, s2=s2))
    stats.patterns = {int(k[4:]): v for k, v in arrays.items() if k.startswith("pat_")}
    return stats


def stats_arrays(stats: PassStats) -> dict[str, np.ndarray]:
    out = {}
    for g, grp in enumerate(stats.groups):
        if grp.n:
            out[f"s1_{g}"], out[f"s2_{g}"] = grp.s1, grp.s2
    out.update({f"pat_{k}": v for k, v in stats.patterns.items()})
    return out


@dataclass
class Progress:
    """Where a capture is: the schedule, the pass under way and its partial image."""

    sched: Schedule
    stats: PassStats
    step: int = 0
    partial: np.ndarray | float = 0.0
    partial_pats: dict = field(default_factory=dict)
    steps_done: int = 0
    resumed_from: int = 0
    predicted_s: float = 0.0
    """Seconds the planned passes still need (after a pilot, :func:`predict_seconds`)."""

    def state(self) -> dict:
        return {"schedule": asdict(self.sched), "step": self.step, "steps_done": self.steps_done}

    def arrays(self) -> dict[str, np.ndarray]:
        out = stats_arrays(self.stats)
        if self.step:
            out["partial"] = np.asarray(self.partial)
            out.update({f"cur_{k}": v for k, v in self.partial_pats.items()})
        return out


def resume(state: dict, arrays: dict) -> Progress:
    """The :class:`Progress` a checkpoint holds."""
    sched = Schedule(**state["schedule"])
    prog = Progress(sched, group_stats(sched, arrays), int(state["step"]))
    prog.steps_done = int(state["steps_done"])
    if prog.step:
        prog.partial = arrays["partial"]
        prog.partial_pats = {int(k[4:]): v for k, v in arrays.items() if k.startswith("cur_")}
    return prog


def check_state(state: dict, arrays: dict, shape: tuple, n_steps: int) -> str | None:
    """Why a checkpoint does not fit a capture of ``shape`` and ``n_steps`` steps per pass, or
    None: a tampered count or a missing array must never pass as finished work."""
    sched = Schedule(**state["schedule"])
    step, done = int(state["step"]), int(state["steps_done"])
    if sched.phase not in ("fixed", "pilot", "main") or not 0 <= step < max(n_steps, 1):
        return f"phase {sched.phase!r}, step {step} of {n_steps}"
    if any(int(s) < 1 or int(n) < 0 for s, n in sched.groups) or sched.planned < 1:
        return f"pass groups {sched.groups}"
    if sched.done_passes > sched.planned or done != sched.done_passes * n_steps + step:
        return f"{done} steps done for {sched.done_passes} passes"
    for g, (_, n) in enumerate(sched.groups):
        for key in (f"s1_{g}", f"s2_{g}") if n else ():
            if key not in arrays or arrays[key].shape != shape:
                return f"{key} missing or not {shape}"
    if step and ("partial" not in arrays or arrays["partial"].shape != shape):
        return f"the pass under way is missing or not {shape}"
    return None


def render_pass_steps(exp: Exposure, prog: Progress, spec, run, store, bar) -> bool:
    """Render the pass under way from ``prog.step`` on; False when a signal stopped it."""
    from ..render.passes import render_passes

    group, spp = prog.sched.next_pass()
    j = prog.sched.done_passes
    steps = exp.steps(spp)
    last_save = time.perf_counter()
    for k in range(prog.step, len(steps)):
        st = steps[k]
        seed, u = step_draws(spec.seed, j, k)
        if exp.moving:
            at = step_time(st.t0, st.t1, u)
            exp.animator.set_time(at - exp.mid_ms)
            exp.sensor.configure(time_window=(st.t0, st.t1, at))
        img = render_passes(exp.scene, st.spp, seed, run.signalled, sensor=exp.sensor)
        if img is None:  # a signal came during the step: keep only the steps before it
            return False
        prog.partial = prog.partial + img
        if spec.per_pattern and exp.moving:
            prog.partial_pats[st.pattern] = prog.partial_pats.get(st.pattern, 0.0) + img
        prog.step, prog.steps_done = k + 1, prog.steps_done + 1
        bar.update(1)
        if prog.step == len(steps):
            break
        if run.stop_after(prog.steps_done) or run.signalled():
            return False
        if time.perf_counter() - last_save > run.save_every_s:
            store.save(prog.state(), prog.arrays())
            last_save = time.perf_counter()
    prog.stats.add(group, prog.partial, prog.partial_pats)
    prog.sched.groups[group][1] += 1
    prog.step, prog.partial, prog.partial_pats = 0, 0.0, {}
    return True


class CaptureInterrupted(RuntimeError):
    """The capture stopped early (``stop_after_steps``, SIGINT or SIGTERM); the finished steps
    are on disk when a ``partial_dir`` was given."""

    def __init__(self, message: str, done: int = 0, total: int = 0, signum: int | None = None):
        super().__init__(message)
        self.done, self.total, self.signum = done, total, signum


@dataclass(frozen=True)
class Run:
    """How to run the steps: where to keep finished ones, progress, deliberate interruption,
    and the flag that SIGINT and SIGTERM set (:func:`~.checkpoint.deferred_signals`)."""

    partial_dir: Any
    progress: bool
    save_every_s: float
    stop_after_steps: int | None
    max_steps: int = DEFAULT_MAX_STEPS
    flag: dict = field(default_factory=lambda: {"signal": None})
    max_samples: int = 0
    pilot_only: bool = False

    def signalled(self) -> bool:
        return self.flag["signal"] is not None

    def stop_after(self, steps_done: int) -> bool:
        return self.stop_after_steps is not None and steps_done >= self.stop_after_steps

    def check_signal(self) -> None:
        """Stop a capture that has no finished steps to save."""
        if self.signalled():
            raise interrupted(0, 0, self.flag["signal"], None)


def interrupted(done: int, total: int, signum, partial_dir) -> CaptureInterrupted:
    import signal

    why = "stopped" if signum is None else f"interrupted ({signal.Signals(signum).name})"
    if total == 0:
        return CaptureInterrupted(f"{why} before any time step finished; nothing to resume")
    where = (
        f"; they are saved in {partial_dir}: run the same command again to resume"
        if partial_dir is not None
        else "; nothing was saved (no partial_dir)"
    )
    return CaptureInterrupted(f"{why} after {done} of {total} steps{where}", done, total, signum)


def integrate(exp: Exposure, spec, run: Run, store, target=None, record=None, desc="") -> Progress:
    """Render a capture's passes (see the module docstring), resuming from ``store``.

    Parameters
    ----------
    exp : Exposure
        The scene, sensor and time steps.
    spec : CaptureSpec
        Uses ``seed``, ``spp``, ``passes`` and ``per_pattern``.
    run : Run
        Signals, progress, saving and the sample limit (``max_samples`` / pixels per pixel).
    store : Checkpoint
        Where finished work is kept.
    target : NoiseTarget, optional
        Render to this Monte Carlo sigma instead of ``spec.spp``.
    record : CaptureRecord, optional
        What ``target`` needs to know of the capture (its light factor and exposure).
    desc : str, optional
        The progress bar's label.

    Returns
    -------
    Progress
        The finished schedule and the passes' statistics; ``steps_done`` counts every step
        rendered, ``resumed_from`` (an attribute) the steps that were on disk.

    Raises
    ------
    CaptureInterrupted
        When ``run`` says stop, or on a signal; the work done so far is saved first.
    """
    from tqdm import tqdm

    shape = _shape(exp)
    n_steps = max(1, len(exp.windows))
    loaded = store.load(lambda st, ar: check_state(st, ar, shape, n_steps))
    if loaded is not None:
        prog = resume(*loaded)
    else:
        max_spp = max(1, run.max_samples // exp.pixels) if run.max_samples else 2**62
        sched = fixed_schedule(spec, exp) if target is None else pilot_schedule(exp, max_spp)
        prog = Progress(sched, group_stats(sched, {}))
    prog.resumed_from = prog.steps_done
    bar = tqdm(total=prog.sched.planned * n_steps, initial=prog.steps_done, unit="step",
               disable=not run.progress, desc=desc, leave=False)  # fmt: skip
    with bar:
        while prog.sched.next_pass() is not None:
            if not render_pass_steps(exp, prog, spec, run, store, bar):
                _stop(prog, run, store, n_steps)
            advance(prog.sched, prog.stats, exp, target, record)
            if run.pilot_only and prog.sched.phase != "pilot":
                prog.predicted_s = predict_seconds(exp, prog, spec)
                break  # the rest is planned: stop here (the caller keeps the checkpoint)
            bar.total = prog.sched.planned * n_steps
            if prog.stats.ready():
                bar.set_postfix_str(_postfix(prog), refresh=False)
            more = prog.sched.next_pass() is not None
            if more and (run.stop_after(prog.steps_done) or run.signalled()):
                _stop(prog, run, store, n_steps)
    return prog


def predict_seconds(exp: Exposure, prog: Progress, spec) -> float:
    """The seconds the planned passes still need: one step of a main pass is rendered and
    timed (then dropped), since a pilot pass of the smallest size is mostly per-step overhead
    and would not scale with the samples. Geometry and window are those of that step."""
    from ..render.passes import render_passes

    spp = prog.sched.groups[-1][0]
    steps = exp.steps(spp)
    st = steps[0]
    if exp.moving:
        exp.animator.set_time(0.5 * (st.t0 + st.t1) - exp.mid_ms)
        exp.sensor.configure(time_window=(st.t0, st.t1, 0.5 * (st.t0 + st.t1)))
    t0 = time.perf_counter()
    render_passes(exp.scene, st.spp, spec.seed, sensor=exp.sensor)
    per_step = time.perf_counter() - t0
    left = prog.sched.planned - prog.sched.done_passes
    return per_step * sum(s.spp for s in steps) / st.spp * left


def _shape(exp: Exposure) -> tuple[int, int, int]:
    w, h = (int(v) for v in exp.sensor.film().crop_size())
    return (h, w, 3)


def _stop(prog: Progress, run: Run, store, n_steps: int):
    """Save what is done and raise :class:`CaptureInterrupted`."""
    if prog.steps_done == 0:
        run.check_signal()
    store.save(prog.state(), prog.arrays())
    total = prog.sched.planned * n_steps
    raise interrupted(prog.steps_done, total, run.flag["signal"], run.partial_dir)


def _postfix(prog: Progress) -> str:
    sigma = rms(prog.stats.variance())
    goal = prog.sched.target_sigma
    return f"MC sigma {sigma:.3g}" + ("" if goal is None else f" (target {goal:.3g})")
