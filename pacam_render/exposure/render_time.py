"""The planner's cost model: how long a capture's renders take, said before they start.

A capture's time is close to linear in counts that its plan fixes before any render: its render
calls (each loads the scene; the first in a process also compiles or loads the kernels), its
camera samples (pixels x spp, over every pass, the ``sharp`` truth layer's included) and its
Mitsuba renders (time steps x passes; each re-poses the moving geometry and launches one):

    seconds = s_call * calls + s_first * first calls + s_msample * M samples
              + s_render * renders.

A PSF render (:mod:`pacam_render.psf_render`) counts the same way, its particles for samples.
The rates are fitted by non-negative least squares (residuals over the square root of the
seconds) to this machine's earlier render calls of the same kind and variant (the history
key): every render call appends its counts and seconds to a history file
(:func:`history_path`). With fewer than :data:`MIN_HISTORY` of them the
:data:`REFERENCE_RATES` are used, and the estimate says so.
``benchmarks/bench_cost_model.py`` measures the estimate's error against the renders it
predicts: a median of 19 % and at most 29 % on held-out captures from 160x120 to 672x701 px
(a sample costs more in a large window than in a small one, and more through a wide opening,
which the model does not know).

A capture rendered to a noise target plans its main passes from its pilot
(:mod:`.progress`): only the pilot is predicted here, and the progress bar's total grows once
the pilot has measured the error.
"""

from __future__ import annotations

import json
import math
import os
import stat
import time
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..limits import DEFAULT_MAX_STEPS, duration
from ..render.samplers import quantum
from ..scenes import load_scene
from ..scenes.assets import cache_root
from .estimate import PILOT_PASSES
from .optics.cost import optics_seconds
from .optics.diffraction import preview_sampling
from .plan import CapturePlan, plan_capture
from .steps import Exposure, exposure_windows

MIN_HISTORY = 4
"""Earlier renders of a history key needed before their fit replaces :data:`REFERENCE_RATES`."""
HISTORY_KEPT = 120
"""The most recent renders per key that the fit uses (the file keeps twice as many)."""
MAX_HISTORY_BYTES = 2**20
"""The most of the history read, from its end: ten times what it holds when trimmed (2 x
:data:`HISTORY_KEPT` rows of about 200 bytes, trimmed past 96 kB), so that a history that is
a huge file costs no more (``PACAM_RENDER_TIMES`` at /dev/zero ran out of memory)."""
MAX_LINE_BYTES = 4096
"""A history line longer than this is not a row (a row takes about 180 bytes): skipped."""
OUTLIER_FACTOR = 100.0
"""A history row whose seconds per reference second (its seconds over what
:data:`REFERENCE_RATES` predict for its counts) is this far from the median of the others' is
left out of the fit: a hand edit or a machine under other load, not this machine's rate (one
row of 10^12 s made an estimate of 5.8e+08 h)."""
FIELDS = ("calls", "first_calls", "msamples", "renders")
"""The counts of :class:`Work`, in the order of a :class:`Rates`' seconds."""
REFERENCE_RATES = {
    "capture": (0.043, 1.03, 0.072, 0.017),
    "psf": (0.0, 0.001, 0.053, 0.0052),
    "lightfield": (0.0, 6.0, 1.54, 0.067),
}
"""Seconds per call, per first call in a process, per million samples (a PSF's: particles)
and per render of ``llvm_ad_rgb`` on the 2-core reference machine, for captures and for PSF
renders (a history key that starts with ``psf``): fitted by
``python benchmarks/bench_cost_model.py`` to its calibration captures of the train scene and
to ``validate-psf --quick``'s renders; and for light-field stores (a history key that starts
with ``lightfield``: samples traced with their records, renders = shards, the first call the
scene's load and the truth layers), fitted to three stores of the train window (48x32 to
160x64, 64 to 512 samples per pixel, 16 to 128 shards) on a loaded 2-core machine."""


@dataclass(frozen=True)
class Work:
    """What render calls do: the calls, the first in its process, the camera samples
    (millions) and the Mitsuba renders (:data:`FIELDS`)."""

    calls: int = 0
    first_calls: int = 0
    msamples: float = 0.0
    renders: int = 0

    def __add__(self, other: Work) -> Work:
        return Work(*(getattr(self, k) + getattr(other, k) for k in FIELDS))

    def vector(self) -> np.ndarray:
        return np.array([float(getattr(self, k)) for k in FIELDS])


@dataclass(frozen=True)
class Rates:
    """Seconds per count of :class:`Work` (:data:`FIELDS`, :func:`rates`), and what they were
    fitted to (``basis``, for the message)."""

    per: tuple
    basis: str

    def seconds(self, work: Work) -> float:
        return float(np.dot(self.per, work.vector()))


@dataclass(frozen=True)
class Estimate:
    """A capture's predicted parts (name to :class:`Work`) and seconds, at ``rates``."""

    parts: dict
    rates: Rates
    what: str = "samples"
    """What :attr:`Work.msamples` counts, for the message (a PSF render's: particles)."""
    optics: dict = field(default_factory=dict)
    """The optics budget's parts (name to seconds, :func:`~.optics.cost.optics_seconds`)."""

    def part_seconds(self) -> dict:
        return {**{k: self.rates.seconds(w) for k, w in self.parts.items()}, **self.optics}

    @property
    def seconds(self) -> float:
        return sum(self.part_seconds().values())

    def describe(self) -> str:
        """``about 12 s (capture 9.1 s, truth 2.3 s; 21 M samples in 70 renders, ...)``."""
        total = sum(self.parts.values(), Work())
        each = ", ".join(f"{k} {duration(s)}" for k, s in self.part_seconds().items())
        return (
            f"about {duration(self.seconds)} ({each}; {total.msamples:.3g} M {self.what} in "
            f"{total.renders} renders, at the rates of {self.rates.basis})"
        )


# ============================================================================================
# The history of renders on this machine
# ============================================================================================
def history_path() -> Path:
    """``$PACAM_RENDER_TIMES``, else ``render_times.jsonl`` in the asset cache's folder."""
    env = os.environ.get("PACAM_RENDER_TIMES", "").strip()
    if env:
        return Path(env).expanduser()

    return cache_root() / "render_times.jsonl"


def remember(key: str, work: Work, seconds: float) -> None:
    """Append one finished render call to the history; a history that cannot be written, or
    is not a regular file (a device, a pipe, a folder), is skipped (the estimate then keeps
    the rates it had: nothing is lost but accuracy)."""
    row = {k: getattr(work, k) for k in FIELDS}
    row["msamples"] = round(work.msamples, 6)
    line = json.dumps({"key": key, **row, "seconds": round(seconds, 4),
                       "cores": os.cpu_count(), "time": round(time.time())})  # fmt: skip
    path = history_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # non-blocking: a pipe with no reader fails at once instead of waiting for one
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK, 0o666)
        with open(fd, "a", encoding="utf-8") as fh:  # one short line: an atomic append
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                return
            fh.write(line + "\n")
        if path.stat().st_size > 400 * HISTORY_KEPT * 2:
            _trim(path)
    except OSError:
        return


def _trim(path: Path) -> None:
    """Keep the newest 2 x :data:`HISTORY_KEPT` lines (written aside, then renamed)."""
    lines = _tail_lines(path)[-2 * HISTORY_KEPT :]
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    os.replace(tmp, path)


class _NotAHistory(OSError):
    """The history's path names something other than a regular file."""


def _tail_lines(path: Path) -> list[str]:
    """The history's lines in its last :data:`MAX_HISTORY_BYTES` (all of a trimmed one),
    without those over :data:`MAX_LINE_BYTES` or cut by the start of the read.

    Raises
    ------
    OSError
        The file cannot be read; :class:`_NotAHistory` when it is not a regular file (a
        device such as /dev/zero never ends, a pipe waits for a writer).
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a pipe opens without waiting
    st = os.fstat(fd)  # what was opened, links followed: no swap after a check
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise _NotAHistory(f"{path} is not a regular file")
    with open(fd, "rb") as fh:
        start = max(0, st.st_size - MAX_HISTORY_BYTES)
        fh.seek(start)
        data = fh.read(MAX_HISTORY_BYTES)
    lines = data.split(b"\n")[1 if start else 0 :]  # the first line read from mid-file is cut
    return [ln.decode("utf-8", "replace") for ln in lines if 0 < len(ln) <= MAX_LINE_BYTES]


def _history(key: str) -> tuple[list[dict], str]:
    """The newest :data:`HISTORY_KEPT` rows of ``key``, and why the history was not read
    (``""`` when it was, or when there is none yet)."""
    path = history_path()
    try:
        lines = _tail_lines(path)
    except FileNotFoundError:
        return [], ""
    except _NotAHistory:
        return [], f"; {path} not read: not a regular file"
    except OSError as exc:
        return [], f"; {path} not read ({exc.strerror or exc})"
    rows = []
    for line in lines:
        try:
            row = json.loads(line)
            counts = [float(row[k]) for k in ("seconds", *FIELDS)]
            ok = row["key"] == key and counts[0] > 0 and all(0 <= v < math.inf for v in counts)
        except (ValueError, KeyError, TypeError, RecursionError):
            continue  # a line cut by a crash, or a hand edit: not evidence
        if ok:
            rows.append(row)
    return rows[-HISTORY_KEPT:], ""


def fit_rates(rows: list[dict], reference: tuple = REFERENCE_RATES["capture"]) -> tuple | None:
    """The seconds per count (:data:`FIELDS`) by non-negative least squares over ``rows`` (each
    the counts and ``seconds``), each residual divided by the square root of its seconds:
    between the relative error, where a short render's start-up noise rules, and the absolute,
    where the long renders that an estimate matters for do. None when fewer than
    :data:`MIN_HISTORY` rows or none varies the samples. A count that moves with another (every
    call the first of its process, say) is left to the other; one never seen keeps the
    ``reference`` rate, scaled as the fitted ones are."""
    from scipy.optimize import nnls

    if len(rows) < MIN_HISTORY:
        return None
    a = np.array([[float(r[k]) for k in FIELDS] for r in rows])
    s = np.array([float(r["seconds"]) for r in rows])
    seen = [j for j in range(len(FIELDS)) if a[:, j].any()]
    used = list(seen)
    while used and np.linalg.matrix_rank(a[:, used] / a[:, used].max(axis=0)) < len(used):
        used.pop(0)  # a count that moves with another (every call a first one): the other has it
    if FIELDS.index("msamples") not in used:
        return None
    w = 1.0 / np.sqrt(s)
    x, _ = nnls(a[:, used] * w[:, None], s * w)
    ref = np.array(reference)
    fitted = [(j, v) for j, v in zip(used, x) if v > 0]
    scale = float(np.median([v / ref[j] for j, v in fitted])) if fitted else 1.0
    full = np.where(np.isin(np.arange(len(FIELDS)), seen), 0.0, ref * scale)  # never seen
    full[used] = x
    return tuple(float(v) for v in full)


def plausible_rows(rows: list[dict], reference: tuple) -> tuple[list[dict], int]:
    """``rows`` less those far from the rest (:data:`OUTLIER_FACTOR`), and how many were left
    out.

    Parameters
    ----------
    rows : list of dict
        History rows (the counts of :data:`FIELDS` and ``seconds``).
    reference : tuple
        The reference rates that put rows of different work on one scale.

    Returns
    -------
    list of dict, int
        The rows kept, in order, and the number left out (none of fewer than three rows: two
        cannot tell which is off).
    """
    if len(rows) < 3:
        return rows, 0
    a = np.array([[float(r[k]) for k in FIELDS] for r in rows])
    s = np.array([float(r["seconds"]) for r in rows])
    pred = a @ np.asarray(reference, float)
    ratio = np.divide(s, pred, out=np.full_like(s, np.inf), where=pred > 0)  # no work: inf
    keep = []
    for i in range(len(rows)):
        others = float(np.median(np.delete(ratio, i)))
        keep.append(others / OUTLIER_FACTOR <= ratio[i] <= others * OUTLIER_FACTOR)
    return [r for r, k in zip(rows, keep) if k], len(rows) - sum(keep)


def rates(key: str) -> Rates:
    """This machine's rates for the history key ``key`` (a variant, or ``psf`` and a variant:
    :func:`fit_rates` on its history less the rows far from the rest, :func:`plausible_rows`),
    else the reference machine's."""
    rows, unread = _history(key)
    kind = next((k for k in ("psf", "lightfield") if key.startswith(k)), "capture")
    reference = REFERENCE_RATES[kind]
    rows, dropped = plausible_rows(rows, reference)
    odd = (
        f"; {dropped} row(s) over {OUTLIER_FACTOR:g}x off the others' seconds left out"
        if dropped
        else ""
    )
    fitted = fit_rates(rows, reference)
    if fitted is None:
        have = f"; {len(rows)} earlier render(s) here" if rows else ""
        return Rates(reference, f"a 2-core reference machine{have}{odd}{unread}")
    return Rates(fitted, f"{len(rows)} earlier {key} renders on this machine{odd}")


# ============================================================================================
# A capture's work, from its plan
# ============================================================================================
def pass_work(exp, spp: int, passes: int) -> Work:
    """The samples and renders of ``passes`` passes of ``spp`` samples over ``exp``'s steps
    (:class:`~.steps.Exposure`)."""
    steps = exp.steps(spp)
    m = passes * exp.pixels * sum(s.spp for s in steps) / 1e6
    return Work(msamples=m, renders=passes * len(steps))


def capture_parts(exp, spec, lens: bool, targeted: bool, truth: bool, preview: bool, first) -> dict:
    """The parts of a capture (name to :class:`Work`): diffraction ``auto``'s ``preview``
    (:func:`~pacam_render.exposure.direct.preview_scene`: a call of its own, two static passes),
    the capture's passes (its pilot when ``targeted``), and the ``sharp`` truth layer's static
    passes (in the capture's call); the first call is its process's first when ``first``."""

    parts = {}
    if preview:
        frozen = replace(exp, windows=[], quantum=1)
        n, passes = preview_sampling(spec.sampler, exp.steps(-(-spec.spp // spec.passes)))
        parts["preview"] = Work(1, int(first)) + pass_work(frozen, n, passes)
    call = Work(1, int(first and not preview))
    if targeted:
        parts["pilot"] = call + pass_work(exp, exp.pass_quantum(), PILOT_PASSES)
    else:
        parts["capture"] = call + pass_work(exp, -(-spec.spp // spec.passes), spec.passes)
    if truth and lens and not targeted:  # a targeted truth follows the target, unknown yet
        static = replace(exp, windows=[])  # the reference is its own sharp layer
        parts["truth"] = pass_work(static, -(-spec.spp // spec.passes), spec.passes)
    return parts


def planned_exposure(plan, desc, max_steps: int = DEFAULT_MAX_STEPS) -> Exposure:
    """The :class:`~.steps.Exposure` a capture's passes will render (no scene loaded): its time
    steps planned from the scene's description and the aperture's patterns, as the render plans
    them."""
    spec = plan.spec
    w, h = spec.image_size
    exp = Exposure(None, None, quantum=quantum(spec.sampler), pixels=w * h)
    if plan.lens and not desc.is_static:
        aperture = plan.aperture()
        exp.windows = exposure_windows(desc, plan.design, plan.cam, spec, aperture, max_steps)[0]
    return exp


def planned_steps(plan, desc, max_steps: int = DEFAULT_MAX_STEPS) -> list:
    """The :class:`~.steps.Step` s of one of a capture's passes, as its render will take them
    (one for a still scene)."""
    spec = plan.spec
    return planned_exposure(plan, desc, max_steps).steps(-(-spec.spp // spec.passes))


def planned_spp(plan, desc, max_steps: int = DEFAULT_MAX_STEPS) -> int:
    """The samples per pixel a capture's passes take over every step (its record's
    ``effective_spp``): ``spec.spp``, or more where each pattern needs one step of at least the
    sampler's smallest render (a 32-pattern design at 16 spp takes 256)."""
    return plan.spec.passes * sum(s.spp for s in planned_steps(plan, desc, max_steps))


def estimate_capture(
    plan, description=None, targeted: bool = False, truth: bool = True,
    max_steps: int = DEFAULT_MAX_STEPS, first: bool | None = None,
) -> Estimate:  # fmt: skip
    """A capture's :class:`Estimate`, before any render: its time steps are planned from the
    scene's description and the aperture's patterns, as the render plans them.

    Parameters
    ----------
    plan : CapturePlan or CaptureSpec
        The capture (a spec is resolved with :func:`~.plan.plan_capture`).
    description : SceneDescription, optional
        The scene, if not ``plan.spec.scene``.
    targeted : bool, optional
        Rendered to a noise target: only the pilot is predicted.
    truth : bool, optional
        With the ground-truth layers.
    max_steps : int, optional
        The most time steps allowed.
    first : bool, optional
        Whether its first render call is its process's first (default: whether none has been
        made yet).
    """

    plan = plan if isinstance(plan, CapturePlan) else plan_capture(plan)
    spec = plan.spec
    desc = description if description is not None else load_scene(spec.scene)
    exp = planned_exposure(plan, desc, max_steps)
    preview = plan.lens and spec.diffraction == "auto" and plan.diffraction is None
    first = not process_warm() if first is None else first
    parts = capture_parts(exp, spec, plan.lens, targeted, truth, preview, first)
    optics = optics_seconds(plan, preview, truth and not targeted)
    return Estimate(parts, rates(plan.variant), optics=optics)


# ============================================================================================
# What a render call did, and the bar over several
# ============================================================================================
_METER: ContextVar = ContextVar("pacam_render_meter", default=None)
_CALLS = [0]  # render calls begun in this process
_OVERALL: ContextVar = ContextVar("pacam_overall_bar", default=None)


@contextmanager
def metered(key: str):
    """Count the steps rendered inside (:func:`count_step`) and, when the block finishes
    without an exception, :func:`remember` them with its seconds."""
    box = [Work(calls=1, first_calls=int(_CALLS[0] == 0))]
    _CALLS[0] += 1
    token = _METER.set(box)
    t0 = time.perf_counter()
    try:
        yield box
    finally:
        _METER.reset(token)
    remember(key, box[0], time.perf_counter() - t0)


def count_step(msamples: float) -> None:
    """One render step of ``msamples`` million samples: counted by the enclosing
    :func:`metered` block; moves the enclosing :class:`Overall` bar, if any."""
    box = _METER.get()
    if box is not None:
        box[0] = box[0] + Work(msamples=msamples, renders=1)
    bar = _OVERALL.get()
    if bar is not None:
        bar.step(Work(msamples=msamples, renders=1))


class Overall:
    """One progress bar over a command's stages, in predicted seconds: each render step moves
    it by its own predicted time, and each stage ends at its predicted share, so that the ETA
    (tqdm's, from the rate so far) covers the whole command."""

    def __init__(self, stages: dict, rates: Rates, desc: str, progress: bool):
        from tqdm import tqdm

        self.stages, self.rates = stages, rates
        self.total = float(sum(stages.values()))
        fmt = "{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}"
        self.bar = tqdm(total=self.total, desc=desc, disable=not progress, bar_format=fmt)
        self._end = self.n = 0.0  # predicted seconds: where the current stage ends, where we are

    @contextmanager
    def stage(self, name: str):
        """Steps rendered inside move the bar; at its end the bar stands at the stage's end."""
        self._end = min(self.total, self._end + self.stages[name])
        token = _OVERALL.set(self)
        try:
            yield
        finally:
            _OVERALL.reset(token)
            self._move(self._end - self.n)

    def step(self, work: Work) -> None:
        self._move(min(self._end - self.n, self.rates.seconds(work)))

    def _move(self, seconds: float) -> None:
        self.n += seconds
        self.bar.update(seconds)

    def __enter__(self) -> Overall:
        return self

    def __exit__(self, *exc) -> None:
        self.bar.close()


def overall_bar(
    captures: dict, name: str, progress: bool, extra: dict | None = None, description=None
) -> Overall:
    """Predict a command's captures (name to (plan or spec, with truth layers)) and its
    ``extra`` stages (name to seconds, predicted by their own models), say the estimate on
    stderr with ``progress``, and return one :class:`Overall` bar over them, in that order.
    The first capture warms the process for the others."""
    cold = not process_warm()
    ests = {key: estimate_capture(plan, description, truth=truth, first=cold and i == 0)
            for i, (key, (plan, truth)) in enumerate(captures.items())}  # fmt: skip
    stages = {key: est.seconds for key, est in ests.items()} | (extra or {})
    rates = next(iter(ests.values())).rates
    if progress:
        each = ", ".join(f"{k} {duration(v)}" for k, v in stages.items())
        say(f"estimate: {name} about {duration(sum(stages.values()))} ({each}; at the rates "
            f"of {rates.basis})")  # fmt: skip
    return Overall(stages, rates, name, progress)


def process_warm() -> bool:
    """Whether a render call has begun in this process (the next is not its first)."""
    return _CALLS[0] > 0


def in_overall() -> bool:
    """Whether a :class:`Overall` bar is under way (its command said the estimate)."""
    return _OVERALL.get() is not None


def say(text: str) -> None:
    """A line on stderr that leaves the progress bars whole (``tqdm.write``)."""
    import sys

    from tqdm import tqdm

    tqdm.write(text, file=sys.stderr)
