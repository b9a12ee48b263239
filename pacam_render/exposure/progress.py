"""How a capture's passes go (:class:`Schedule`), and where a capture is (:class:`Progress`):
what a checkpoint holds, and the checks it must pass before it is trusted.

Without a target a capture is ``passes`` passes of spp / passes samples. With a target
(:class:`~.estimate.NoiseTarget`), two pilot passes of the smallest size measure the error, the
samples the target needs are predicted from them (sigma^2 ~ 1 / N), and the rest is rendered as
:data:`~.estimate.MAIN_PASSES` equal passes; the capture stops after any of them once its
Monte Carlo sigma meets the target, adds passes while it does not, and stops at the sample
limit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from .estimate import MAIN_PASSES, PILOT_PASSES, PassGroup, PassStats, main_pass_spp, rms
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
