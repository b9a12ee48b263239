"""How a capture's passes go (:class:`Schedule`), and where a capture is (:class:`Progress`):
what a checkpoint holds, and the checks it must pass before it is trusted.

Without a target a capture is ``passes`` passes of spp / passes samples. With a target
(:class:`~.estimate.NoiseTarget`), two pilot passes of the smallest size measure the error, the
samples the target needs are predicted from them (sigma^2 ~ 1 / N), and the rest is rendered as
:data:`~.estimate.MAIN_PASSES` equal passes; the capture stops after any of them once its
Monte Carlo sigma meets the target. If two main passes do not meet it, :func:`replan` fits one
pass's variance as a + b / spp over the pilot and main groups (``a``: the poses a moving pass
draws once per step, which more samples do not lower) and plans the rest at the pass size that
costs least; the sample limit stops it.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ..limits import check_count, duration
from .estimate import (
    MAIN_PASSES,
    MARGIN,
    PILOT_PASSES,
    PassGroup,
    PassStats,
    main_pass_spp,
    pass_variance_fit,
    passes_to_target,
    rms,
    spp_to_target,
)
from .steps import Exposure


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


def check_samples(sched: Schedule, exp: Exposure, spec, max_samples: int) -> None:
    """Refuse, before any render, passes whose samples exceed ``max_samples`` as they will be
    rendered: a fixed capture's passes once the steps have rounded them (each step takes at
    least the sampler's smallest render), or a targeted capture's pilot passes.

    Parameters
    ----------
    sched : Schedule
        The passes planned (fixed, a pilot, or a resumed main phase).
    exp : Exposure
        The steps and pixels of a pass.
    spec : CaptureSpec
        Uses ``spp``, ``sampler`` and ``image_size``, for the message.
    max_samples : int
        The limit, camera samples (0: none).

    Raises
    ------
    ParameterError
        Naming ``max_samples``, the spp that will be rendered and why they exceed ``spec.spp``.
    """

    if not max_samples:
        return
    w, h = spec.image_size
    spp, per = sched.planned_spp, sched.groups[-1][0]
    least = f"{sched.planned} passes of at least {exp.quantum} spp"
    least += (
        f" per time step ({spec.sampler}), {exp.steps_per_pass(per)} steps"
        if exp.moving
        else f" ({spec.sampler})"
    )
    if sched.phase == "pilot":
        why = f"the pilot of this noise target ({least}; "
        hint = "; or render a smaller crop" + (", or raise max_step_px" if exp.moving else "")
    elif sched.phase == "main":  # resumed with a lower limit than it was planned with
        why, hint = "the passes this noise target planned (", ""
    elif spp > spec.spp:
        why = f"this capture ({least}, take {spp} spp where `spp` {spec.spp} was asked; "
        hint = "; or lower `passes`" + (
            ", or raise max_step_px (fewer steps)" if exp.moving else ""
        )
    else:
        why, hint = "this capture (", "; or lower `spp`"
    check_count(
        f"samples of {why}{spp} spp x {w} x {h} px)", spp * exp.pixels, max_samples,
        "max_samples", hint,
    )  # fmt: skip


def pilot_done(sched: Schedule) -> bool:
    """Whether a targeted capture's pilot passes are all rendered and the rest not planned."""
    return sched.phase == "pilot" and sched.done_passes >= sched.planned


def out_of_reach(prog: Progress, exp: Exposure, target, record, max_samples: int) -> str | None:
    """After the pilot: why the target cannot be met within ``max_samples``, or None.

    Parameters
    ----------
    prog : Progress
        The capture, its pilot passes done; its :attr:`Progress.seconds` time them.
    exp : Exposure
        The steps and pixels of a pass.
    target : NoiseTarget
        What to reach.
    record : CaptureRecord
        What ``target`` needs to know of the capture.
    max_samples : int
        The limit, camera samples (0: none).

    Returns
    -------
    str or None
        The message, naming ``max_samples`` and the target's parameter (``noise_target`` or
        ``noise_ratio``), with the samples the target takes and their seconds; None when the
        pilot met the target or predicts it within the limit.

    Notes
    -----
    The pilot predicts the samples the target takes at least (:func:`~.estimate.spp_to_target`,
    sigma^2 ~ 1 / N); their seconds are the pilot's, per unit of :func:`pass_cost`, times the
    cost of the rest in :data:`~.estimate.MAIN_PASSES` passes.
    """

    goal = float(target.sigma(prog.stats.mean(), record))
    sigma = rms(prog.stats.variance())
    if not max_samples or sigma <= goal:
        return None
    need = spp_to_target(prog.stats, goal)
    if need * exp.pixels <= max_samples:
        return None
    done = prog.stats.spp
    rest = max(need - done, 1.0) / MAIN_PASSES
    pilot = sum(n * pass_cost(exp, spp) for spp, n in prog.sched.groups)
    seconds = prog.seconds * MAIN_PASSES * pass_cost(exp, math.ceil(rest)) / pilot
    name = "noise_ratio" if target.to_json().get("kind") == "sensor" else "noise_target"
    return (
        f"the noise target is out of reach within max_samples {max_samples}: the pilot's "
        f"{done} spp give a Monte Carlo sigma of {sigma:.3g} against the target's {goal:.3g}, "
        f"and sigma falls as 1 / sqrt(spp), so the target takes at least {need:.4g} spp "
        f"({need * exp.pixels:.4g} samples, about {duration(seconds)} at the pilot's pace), "
        f"where max_samples allows {max_samples // exp.pixels} spp; raise max_samples to "
        f"{math.ceil(need * exp.pixels * MARGIN)} or more, relax {name}, or render "
        "a smaller crop"
    )


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
    else:
        replan(sched, stats, exp)


def replan(sched: Schedule, stats: PassStats, exp: Exposure) -> None:
    """The target is not met after two passes of the group under way: plan the rest from what
    the passes show. One pass's variance is a + b / spp (:func:`~.estimate.pass_variance_fit`),
    its cost that of :func:`pass_cost`; the pass size (from the pilot's up to the current) and
    count that reach the target at the least cost are chosen. When the floor ``a`` of a moving
    scene dominates, many small passes beat a few large ones. If the sample limit comes first,
    passes of the current size go up to it (and the capture says the target was not met)."""
    fit = pass_variance_fit(stats)
    current = sched.groups[-1][0]
    best = None
    for spp in candidate_sizes(exp, current):
        room = (sched.max_spp - sched.spp) // spp
        n = passes_to_target(stats, fit, spp, sched.target_sigma, room)
        if n is not None and spp != current:
            n = max(n, 2)  # a new group: two passes at least, for its own spread
        if n is not None and n <= room:
            cost = n * pass_cost(exp, spp)
            if best is None or cost < best[0]:
                best = (cost, spp, n)
    spp, n = (current, (sched.max_spp - sched.spp) // current) if best is None else best[1:]
    if spp != current:
        sched.groups.append([spp, 0])
        stats.groups.append(PassGroup(spp=spp))
    sched.planned = sched.done_passes + n


def candidate_sizes(exp: Exposure, current: int) -> list[int]:
    """Pass sizes (spp) from the pilot's, doubling, up to ``current``: each keeps every step."""
    out, q = {current}, exp.pass_quantum()
    while q < current:
        out.add(sum(s.spp for s in exp.steps(q)))
        q *= 2
    return sorted(out)


STEP_OVERHEAD_PX_SAMPLES = 1.5e5
"""What one step's render costs beyond its samples (its geometry update and launch), in
pixel-samples: 1.3e5 to 1.8e5 in three runs (wall and CPU seconds) with the LLVM variant on 2
cores, a 200x120 train window at 4 and 64 spp per step
(``benchmarks/bench_render_error.py --part 6``)."""
PASS_OVERHEAD_PX_SAMPLES = 1.4e5
"""What one pass costs beyond its steps (its statistics, the target's check), in pixel-samples:
1.3e5 to 1.4e5 from short captures of 512 spp in 2 and in 32 passes, in the same runs."""


def pass_cost(exp: Exposure, spp: int) -> float:
    """A pass's cost in pixel-samples: its samples, each step's fixed cost and the pass's own.
    A model with fixed constants rather than measured seconds, so that a seed gives one plan
    and one image on any machine."""
    steps = exp.steps_per_pass(spp)
    return spp * exp.pixels + steps * STEP_OVERHEAD_PX_SAMPLES + PASS_OVERHEAD_PX_SAMPLES


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
    seconds_before: float = 0.0
    """Seconds that earlier sessions spent on the work a resumed checkpoint holds."""
    started: float = field(default_factory=time.perf_counter)
    """When this session's work began (``time.perf_counter``)."""

    @property
    def seconds(self) -> float:
        """Seconds spent on the work so far, over every session: :attr:`seconds_before` and
        this session's since :attr:`started`."""
        return self.seconds_before + (time.perf_counter() - self.started)

    def state(self) -> dict:
        return {
            "schedule": asdict(self.sched),
            "step": self.step,
            "steps_done": self.steps_done,
            "seconds": round(self.seconds, 6),
        }

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
    prog.seconds_before = float(state.get("seconds", 0.0))  # none in an older checkpoint
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
    seconds = state.get("seconds", 0.0)
    if (
        isinstance(seconds, bool)
        or not isinstance(seconds, (int, float))
        or not (math.isfinite(seconds) and seconds >= 0)
    ):
        return f"seconds {seconds!r}"
    for g, (_, n) in enumerate(sched.groups):
        for key in (f"s1_{g}", f"s2_{g}") if n else ():
            if key not in arrays or arrays[key].shape != shape:
                return f"{key} missing or not {shape}"
    if step and ("partial" not in arrays or arrays["partial"].shape != shape):
        return f"the pass under way is missing or not {shape}"
    return None
