"""Integrating a capture over its exposure: independent passes, each over the time steps of a
moving scene (:mod:`.steps`), until a sample budget or a noise target is met (:mod:`.progress`),
resumable from a checkpoint and stopped cleanly by a signal.

A static scene is one render per pass: each ray's time selects the pattern in the sensor, so
there is no loop and no geometry update. The passes' spread is the capture's Monte Carlo error
(:mod:`.estimate`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from ..errors import ParameterError
from ..limits import DEFAULT_MAX_STEPS, note
from ..render.passes import render_passes
from .estimate import rms
from .progress import (
    Progress,
    advance,
    check_samples,
    check_state,
    fixed_schedule,
    group_stats,
    out_of_reach,
    pilot_done,
    pilot_schedule,
    resume,
)
from .render_time import count_step
from .steps import Exposure, step_draws, step_time


def render_pass_steps(exp: Exposure, prog: Progress, spec, run, store, bar) -> bool:
    """Render the pass under way from ``prog.step`` on; False when a signal stopped it."""

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
        img = render_passes(
            exp.scene, st.spp, seed, run.signalled, sensor=exp.sensor, on_cut=run.mark_sigint
        )
        if img is None:  # a signal came during the step: keep only the steps before it
            return False
        prog.partial = prog.partial + img
        if spec.per_pattern and exp.moving:
            prog.partial_pats[st.pattern] = prog.partial_pats.get(st.pattern, 0.0) + img
        prog.step, prog.steps_done = k + 1, prog.steps_done + 1
        bar.update(1)
        count_step(exp.pixels * st.spp / 1e6)
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
    truth_sampler: str | None = None
    """The sampler the ``sharp`` truth layer renders with (a still scene at t = 0, which keeps
    the one asked where the time steps took another, :func:`~.steps.fine_step_sampler`)."""

    def signalled(self) -> bool:
        return self.flag["signal"] is not None

    def mark_sigint(self) -> None:
        """Mitsuba's own handler took a SIGINT during a render (Python's never ran)."""
        import signal

        if self.flag["signal"] is None:
            self.flag["signal"] = signal.SIGINT

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
    ParameterError
        Before any render, when the passes as the steps round them (or a target's pilot)
        exceed ``run.max_samples``; after the pilot, when the target is out of reach within
        it (:func:`~.progress.out_of_reach`; the pilot is saved first, and a run with a larger
        limit resumes from it).
    """
    from tqdm import tqdm

    shape = _shape(exp)
    n_steps = max(1, len(exp.windows))
    loaded = store.load(lambda st, ar: check_state(st, ar, shape, n_steps))
    max_spp = max(1, run.max_samples // exp.pixels) if run.max_samples else 2**62
    if loaded is not None:
        prog = resume(*loaded)
        if target is not None:  # this run's limit: a re-run with a larger one plans with it
            prog.sched.max_spp = max_spp
    else:
        sched = fixed_schedule(spec, exp) if target is None else pilot_schedule(exp, max_spp)
        prog = Progress(sched, group_stats(sched, {}))
    check_samples(prog.sched, exp, spec, run.max_samples)
    prog.resumed_from = prog.steps_done
    if prog.steps_done:  # said even when quiet: the capture is partly an earlier run's
        note(f"resumed: {prog.steps_done} finished step(s) of an earlier run, saved in "
             f"{run.partial_dir}, are kept")  # fmt: skip
    if pilot_done(prog.sched):  # a pilot refused as out of reach, resumed: plan the rest now
        _plan_main(exp, prog, run, store, target, record)
    n_steps = exp.steps_per_pass(prog.sched.groups[-1][0])  # a fixed or a main pass
    if run.pilot_only and prog.sched.phase != "pilot":  # resumed past its pilot: only predict
        prog.predicted_s = predict_seconds(exp, prog, spec)
        return prog
    bar = tqdm(total=prog.sched.planned * n_steps, initial=prog.steps_done, unit="step",
               disable=not run.progress, desc=desc, leave=False)  # fmt: skip
    with bar:
        while prog.sched.next_pass() is not None:
            if not render_pass_steps(exp, prog, spec, run, store, bar):
                _stop(prog, run, store, n_steps)
            if pilot_done(prog.sched):
                _plan_main(exp, prog, run, store, target, record)
            else:
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


def _plan_main(exp: Exposure, prog: Progress, run: Run, store, target, record) -> None:
    """The pilot is done: refuse a target out of reach within ``run.max_samples`` at once,
    the pilot saved for a run with a larger limit to resume from; else plan the main passes
    (:func:`~.progress.advance`)."""
    why = out_of_reach(prog, exp, target, record, run.max_samples)
    if why is not None:
        saved = store.save(prog.state(), prog.arrays())
        where = (
            f"; the pilot is saved in {run.partial_dir}: the same command with a larger "
            "max_samples resumes from it"
            if saved
            else ""
        )
        raise ParameterError(why + where)
    advance(prog.sched, prog.stats, exp, target, record)


def predict_seconds(exp: Exposure, prog: Progress, spec) -> float:
    """The seconds the planned passes still need: one step of a main pass is rendered and
    timed (then dropped), since a pilot pass of the smallest size is mostly per-step overhead
    and would not scale with the samples. Geometry and window are those of that step."""

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


def _shape(exp: Exposure) -> tuple[int, ...]:
    """The image's shape: (H, W, C), or (H, W) for a one-channel (grey) film."""
    film = exp.sensor.film()
    w, h = (int(v) for v in film.crop_size())
    channels = int(film.base_channels_count())
    return (h, w) if channels == 1 else (h, w, channels)


def _stop(prog: Progress, run: Run, store, n_steps: int):
    """Save what is done and raise :class:`CaptureInterrupted`."""
    if prog.steps_done == 0:
        run.check_signal()
    saved = store.save(prog.state(), prog.arrays())
    total = prog.sched.planned * n_steps
    raise interrupted(
        prog.steps_done, total, run.flag["signal"], run.partial_dir if saved else None
    )


def _postfix(prog: Progress) -> str:
    sigma = rms(prog.stats.variance())
    goal = prog.sched.target_sigma
    return f"MC sigma {sigma:.3g}" + ("" if goal is None else f" (target {goal:.3g})")
