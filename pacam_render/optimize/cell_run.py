"""``pacam optimize --lightfield STORE ... --space bitmap|discs``: a whole-aperture LCoS
bitmap (:mod:`.cell_search`), or one disc per pattern window moving in 2-D with a radius
(:mod:`.disc_space`), searched by gradient on the stores' cell bases, written as a design file
(a bitmap's masks beside it), and reported with the real pipeline (:mod:`.cell_report`) on each
store's synthesis of the store's own design (the prototype) and of the found one, and on
held-out stores (scenes the search never saw) with paired 95 % intervals.

The objective is the model's moving-object PSNR, or with ``objective="moving+still"`` its
weighted mean in dB with the still pixels' PSNR, pooled over the stores by ``aggregate``: their
mean, or ("worst") the soft minimum of each store's gain over the store's own design
(:mod:`.cell_objective`); the starts are the store's design rasterised on the cells and
``starts - 1`` random binary codes (as open as the prototype, drawn from ``seed``). With
``light="fixed"`` every code keeps the light factor of the store's design's capture (its disc,
not the disc rasterised on the cells)."""

from __future__ import annotations

import gc
import math
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ParameterError, check_integer, check_positive
from ..exposure.plan import plan_capture
from ..lightfield.cell_basis import (
    CELL_CHOICES,
    DEFAULT_CELLS,
    cell_basis,
    display_px,
    estimate_bytes,
    lens_cells,
)
from ..lightfield.store import Store
from ..lightfield.synthesis import refocus_shear, synthesize
from ..limits import available_bytes, gib, note
from ..model.design_file import write_design
from ..sensor.model import SensorModel
from .cell_design import bitmap_design, design_spec, disc_code
from .cell_objective import base_value, cell_problem, check_aggregate
from .cell_report import SCORES, paired, write_patterns, write_report
from .cell_search import LIGHT_CHOICES, gradient_search, light_of
from .cell_select import PROTOTYPE, choose, score_rows, split_passes
from .cell_text import report_text
from .disc_space import DiscGrid, disc_design, disc_search, plan_discs, random_discs, soft_code
from .rendered_run import RenderedProblem, base_spec, open_stores, store_noise

ITERATIONS = 200
"""Adam steps per start (each one objective evaluation with its gradient per store)."""
STARTS = 4
"""Starts: the prototype and 3 random codes."""
MAX_LEVELS = 256
"""The most transmittance levels per cell (an 8-bit grey LCoS); 2 is binary (the prototype's
ferroelectric LCoS)."""
OBJECTIVES = ("moving", "moving+still")
"""What the model scores: the moving objects' PSNR, or its weighted mean in dB with the still
pixels' (:mod:`.cell_objective`)."""
CELL_SPACES = ("bitmap", "discs")
"""The spaces searched on the cells' basis: any bitmap per window, or one disc per window."""
MIN_HELD_OUT = 2
"""Held-out stores a paired interval needs (one difference per store)."""
STILL_WEIGHT = 1.0
"""The still term's weight w in (P_moving + w P_still) / (1 + w) by default: a dB on the moving
objects counts as one on the still regions."""


@dataclass(frozen=True)
class BitmapProblem:
    """What a bitmap search takes: the stores, the cell grid, the light rule and the budget."""

    stores: tuple[str, ...]
    sensor: str = "grasshopper-icx285"
    light_level: float = 300.0
    cells: int = DEFAULT_CELLS
    light: str = "fixed"
    starts: int = STARTS
    iterations: int = ITERATIONS
    seed: int = 0
    noise_draws: int = 2
    levels: int = 2
    objective: str = "moving"
    still_weight: float | None = None
    space: str = "bitmap"
    held_out: tuple[str, ...] = ()
    max_still_loss_db: float | None = None
    held_passes: int | None = None
    lcos_switching_ms: float | None = None
    aggregate: str = "mean"
    focus_mm: tuple[float, ...] = ()
    """Further focus distances (mm) the search tries (:func:`found_over_focus`); empty: the
    store design's own focus only."""

    @property
    def weight(self) -> float:
        """The still term's weight the search takes: 0 for ``moving``."""
        if self.objective == "moving":
            return 0.0
        return STILL_WEIGHT if self.still_weight is None else float(self.still_weight)


def check_bitmap_problem(p: BitmapProblem):
    """The stores (one camera, :func:`~.rendered_run.open_stores`) and every setting checked,
    with the bases' memory, before any work; returns the open stores."""
    check_integer("`starts`", p.starts, 1, None)
    check_integer("`iterations`", p.iterations, 1, None)
    check_integer("`levels`", p.levels, 2, MAX_LEVELS)
    if p.space not in CELL_SPACES:
        raise ParameterError(f"`space`: one of {', '.join(CELL_SPACES)}, got {p.space!r}")
    if p.space == "discs" and p.levels != 2:
        raise ParameterError("`levels`: only the bitmap space takes it (a disc is open or shut)")
    if p.held_out and len(p.held_out) < MIN_HELD_OUT:
        raise ParameterError(f"`held_out`: at least {MIN_HELD_OUT} stores for a paired interval"
                             f" (one difference per store), got {len(p.held_out)}")  # fmt: skip
    d = p.max_still_loss_db
    if d is not None and not (math.isfinite(float(d)) and d >= 0):
        raise ParameterError(f"max_still_loss_db: a finite number >= 0 (dB), got {d!r}")
    if set(map(str, p.held_out)) & set(map(str, p.stores)):
        raise ParameterError("`held_out`: a store the search trains on is not held out")
    if p.light not in LIGHT_CHOICES:
        raise ParameterError(f"`light`: one of {', '.join(LIGHT_CHOICES)}, got {p.light!r}")
    check_objective(p.objective, p.still_weight)
    check_aggregate(p.aggregate)
    every = open_stores(RenderedProblem(tuple(p.stores) + tuple(p.held_out), p.sensor,
                                        p.light_level, noise_draws=p.noise_draws, seed=p.seed,
                                        check_seeds=0))  # fmt: skip
    stores = every[: len(p.stores)]
    if p.held_passes is not None:
        check_integer("held_passes", p.held_passes, 0, None)
    split_passes(p, stores)
    if p.lcos_switching_ms and p.space != "discs":
        raise ParameterError("lcos_switching_ms: only the discs space (the plugin switches "
                             "discs, not bitmaps)")  # fmt: skip
    cam = plan_capture(store_spec(stores[0], p)).cam  # checks lcos_switching_ms
    check_focus(p, stores, cam)
    try:
        display_px(cam.R_max_mm, cam.lcos_pitch_mm, p.cells)
    except ParameterError as exc:
        raise ParameterError(str(exc)) from None
    need = 0
    for s in stores:
        _, _, w, h = s.manifest.camera.window
        need += estimate_bytes(cam.n_patterns, len(lens_cells(p.cells, cam.R_max_mm)), h, w,
                               s.manifest.channels)  # fmt: skip
    if need > available_bytes():
        raise ParameterError(
            f"`cells` {p.cells}: the stores' bases need about {gib(need)}, {gib(available_bytes())}"
            f" is available; take fewer cells (of {list(CELL_CHOICES)}) or fewer stores"
        )
    return stores


def check_objective(objective: str, still_weight: float | None) -> None:
    """``objective`` one of :data:`OBJECTIVES`; ``still_weight`` only with moving+still,
    finite and > 0."""
    if objective not in OBJECTIVES:
        raise ParameterError(f"`objective`: one of {', '.join(OBJECTIVES)}, got {objective!r}")
    if still_weight is None:
        return
    if objective == "moving":
        raise ParameterError("still_weight: only `objective` moving+still takes it")
    w = float(still_weight)
    if not (math.isfinite(w) and w > 0):
        raise ParameterError(f"still_weight: a finite number > 0, got {still_weight!r}")


def store_spec(store, p: BitmapProblem):
    """The capture a store was rendered for (:func:`~.rendered_run.base_spec`), with the
    problem's LCoS switching time."""
    return replace(base_spec(store), lcos_switching_ms=p.lcos_switching_ms)


def prepare_bitmap(p: BitmapProblem, stores, progress: bool = False, specs=None) -> dict:
    """The stores' bases, templates (their design's syntheses, or ``specs``') and objective
    terms.

    Returns
    -------
    dict
        ``specs``, ``plan``, ``bases``, ``templates``, ``base_code`` (the store's design
        rasterised), ``problems`` and ``setup_s``.
    """
    t0 = time.perf_counter()
    specs = [store_spec(s, p) for s in stores] if specs is None else specs
    plan = plan_capture(specs[0])
    base = disc_code(plan, p.cells)
    search, choice = split_passes(p, stores)
    bases = [cell_basis(s, spec, p.cells, progress, passes=search)
             for s, spec in zip(stores, specs)]  # fmt: skip
    templates = [synthesize(s, spec, progress=False, passes=search)
                 for s, spec in zip(stores, specs)]  # fmt: skip
    problems = [cell_problem(b, t, plan, base, p.sensor, p.light_level)
                for b, t in zip(bases, templates)]  # fmt: skip
    return dict(specs=specs, plan=plan, bases=bases, templates=templates, base_code=base,
                problems=problems, setup_s=time.perf_counter() - t0, search_passes=search,
                choice_passes=choice)  # fmt: skip


def search_bitmap(p: BitmapProblem, prepared: dict):
    """:func:`~.cell_search.gradient_search` from the prototype and ``p.starts - 1`` random
    codes on :func:`prepare_bitmap`'s problems, ``p.light`` as the rule, ``p.objective``
    what is scored.

    Returns
    -------
    CellSearch
    """
    problems, base = prepared["problems"], prepared["base_code"]
    rng = np.random.default_rng(p.seed)
    share = light_of(problems[0], base) / light_of(problems[0], np.ones_like(base))
    starts = {"prototype": base}
    for i in range(1, p.starts):
        starts[f"random {i}"] = (rng.random(base.shape) < share).astype(float)
    reference = prepared["templates"][0].record.light_factor  # the disc's, not rasterised
    return gradient_search(problems, starts, p.iterations, levels=p.levels, light=p.light,
                           reference=reference, still_weight=p.weight,
                           aggregate=p.aggregate)  # fmt: skip


def search_discs(p: BitmapProblem, prepared: dict):
    """:func:`~.disc_space.disc_search` from the store design's discs and ``p.starts - 1``
    random centres (its radius) on :func:`prepare_bitmap`'s problems.

    Returns
    -------
    DiscSearch
    """
    plan, cam = prepared["plan"], prepared["plan"].cam
    grid = DiscGrid(p.cells, cam.R_max_mm, cam.lcos_pitch_mm)
    base = plan_discs(plan)
    rng = np.random.default_rng(p.seed)
    starts = {"prototype": base}
    for i in range(1, p.starts):
        starts[f"random {i}"] = random_discs(rng, base, grid)
    return disc_search(prepared["problems"], starts, grid, p.iterations, p.light, p.weight,
                       p.aggregate)  # fmt: skip


def found_design(p: BitmapProblem, prepared: dict) -> dict:
    """The search of ``p.space`` on :func:`prepare_bitmap`'s problems: ``candidates`` (each
    start's found design, named "from START"), ``codes`` (their patterns on the cells, (n, G, G)),
    the model's dB (``model_db``: ``found``, ``relaxed``, ``starts``), the ``curve`` and the
    ``evaluations``."""
    plan = prepared["plan"]
    if p.space == "discs":
        s = search_discs(p, prepared)
        grid = DiscGrid(p.cells, plan.cam.R_max_mm, plan.cam.lcos_pitch_mm)
        codes = {f"from {k}": soft_code(d, grid)[0] for k, d in s.found.items()}
        designs = {f"from {k}": disc_design(plan, d) for k, d in s.found.items()}
        model = {"found": s.model_db, "relaxed": s.model_db, "starts": [list(x) for x in s.starts],
                 "R_mm": {k: d.R_mm for k, d in s.found.items()}}  # fmt: skip
    else:
        s = search_bitmap(p, prepared)
        codes = {f"from {k}": c for k, c in s.codes.items()}
        designs = {k: bitmap_design(plan, prepared["bases"][0], c) for k, c in codes.items()}
        model = {"found": s.projected_db, "relaxed": s.relaxed_db,
                 "starts": [list(x) for x in s.starts]}  # fmt: skip
    return dict(candidates=designs, codes=codes, model_db=model,
                curve=[list(x) for x in s.rows], evaluations=s.evaluations)  # fmt: skip


def check_focus(p: BitmapProblem, stores, cam) -> None:
    """Each of ``p.focus_mm`` finite, > 0 and once, and within every store's refocus margin
    for the lens ``cam``'s (:func:`~..lightfield.synthesis.refocus_shear`)."""
    for f in p.focus_mm:
        check_positive("focus_mm", f, "mm")
    if len(set(map(float, p.focus_mm))) != len(p.focus_mm):
        raise ParameterError(f"focus_mm: each focus once, got {list(p.focus_mm)}")
    for f in p.focus_mm:
        for s in stores:
            refocus_shear(s, float(f), cam.R_max_mm)


def refocused_specs(specs, plan, focus_mm: float, folder: Path) -> list:
    """``specs`` with ``plan``'s design (its discs, opening, windows and exposure) focused at
    ``focus_mm``, through a design file in ``folder`` (the road a user's design takes)."""
    d = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px,
                          pattern_centres_mm=tuple(map(tuple, plan.design.pattern_centres_xy_mm())),
                          focus_distance_mm=float(focus_mm), quoted_a_i_px_per_ms2=None,
                          name=f"the store's design focused at {focus_mm:g} mm")  # fmt: skip
    path = folder / f"focus_{float(focus_mm):g}.toml"
    write_design(path, d, force=True)
    return [design_spec(s, path) for s in specs]


def found_over_focus(p: BitmapProblem, stores, prepared: dict, progress: bool = False) -> dict:
    """:func:`found_design` at the store design's focus (``prepared``) and, one after another
    (one focus's bases in memory at a time), at each of ``p.focus_mm`` from the store's design
    refocused there: every focus's candidates together, named "START @ F mm" (no suffix
    without ``p.focus_mm``). A "worst" search at another focus measures its gains against
    the store's design at its own focus, as the choice does."""
    f = found_design(p, prepared)
    if not p.focus_mm:
        return f
    per_focus = [(prepared["plan"].cam.focus_distance_mm, f)]
    with tempfile.TemporaryDirectory(prefix="pacam-focus-") as tmp:
        for mm in p.focus_mm:
            specs = refocused_specs(prepared["specs"], prepared["plan"], mm, Path(tmp))
            r = prepare_bitmap(p, stores, progress, specs)
            for q, ref in zip(r["problems"], prepared["problems"]):
                q.base_db[p.weight] = base_value(ref, p.weight)
            per_focus.append((float(mm), found_design(p, r)))
            del r
            gc.collect()
    return _merge_focus(per_focus)


def _merge_focus(found: list) -> dict:
    """(focus mm, :func:`found_design`'s dict) pairs as one dict of every focus's candidates,
    each name suffixed with its focus; the curves one after another."""
    out = dict(candidates={}, codes={}, curve=[], evaluations=0,
               model_db={"found": -math.inf, "relaxed": -math.inf, "starts": []})  # fmt: skip
    for mm, f in found:
        tag = f" @ {mm:.0f} mm"
        out["candidates"].update({k + tag: v for k, v in f["candidates"].items()})
        out["codes"].update({k + tag: v for k, v in f["codes"].items()})
        m = f["model_db"]
        out["model_db"]["found"] = max(out["model_db"]["found"], m["found"])
        out["model_db"]["relaxed"] = max(out["model_db"]["relaxed"], m["relaxed"])
        out["model_db"]["starts"] += [[s[0] + tag, *s[1:]] for s in m["starts"]]
        if "R_mm" in m:
            out["model_db"].setdefault("R_mm", {}).update(
                {k + tag: v for k, v in m["R_mm"].items()}
            )
        n, t = len(out["curve"]), out["curve"][-1][1] if out["curve"] else 0.0
        out["curve"] += [[n + row[0], t + row[1], *row[2:]] for row in f["curve"]]
        out["evaluations"] += f["evaluations"]
    return out


def chosen_design(p: BitmapProblem, prepared: dict, stores, f: dict) -> dict:
    """:func:`~.cell_select.choose` on ``f``'s candidates: adds ``choice`` (its result),
    ``design`` and ``code`` (the chosen one's; the store's design, as discs and rasterised,
    where none beat it) to ``f``."""
    held = prepared["choice_passes"]
    refs = prepared["templates"] if held is None else [
        synthesize(s, spec, progress=False, passes=held)
        for s, spec in zip(stores, prepared["specs"])]  # fmt: skip
    c = choose(f["candidates"], stores, prepared["specs"], refs, p, held)
    name = c["chosen"]
    if name == PROTOTYPE:
        f["design"], f["code"] = disc_design(prepared["plan"], plan_discs(prepared["plan"])), \
            prepared["base_code"]  # fmt: skip
    else:
        f["design"], f["code"] = f["candidates"][name], f["codes"][name]
    f["choice"] = c
    return f


def _rows(p: BitmapProblem, folders, stores, path: Path, name: str) -> list[dict]:
    """Report rows of the prototype and the design file at ``path`` (``name``) synthesised
    from each store (:func:`~.cell_select.score_rows`)."""
    specs = [store_spec(s, p) for s in stores]
    templates = [synthesize(s, spec, progress=False) for s, spec in zip(stores, specs)]
    return score_rows(p, folders, stores, specs, templates, {name: path})


def run_bitmap_optimize(p: BitmapProblem, out: Path, force: bool, progress: bool) -> dict:
    """Search, choose (:mod:`.cell_select`), write ``out``/design.toml (a bitmap's masks
    beside it) and report.json/.md/.png and patterns.png: the store's design and every start's
    result synthesised from every training store, the chosen one on every held-out store, all
    scored with the real pipeline, paired intervals on the held-out.

    Returns
    -------
    dict
        The report.json object.
    """
    stores = check_bitmap_problem(p)
    r = prepare_bitmap(p, stores, progress)
    check_still_loss(p, r["problems"])
    f = chosen_design(p, r, stores, found_over_focus(p, stores, r, progress))
    path = out / "design.toml"
    write_design(path, f["design"], force)
    name = f"found {p.space}" if f["choice"]["chosen"] != PROTOTYPE else "kept prototype"
    held = _rows(p, p.held_out, [Store.open(s) for s in p.held_out], path, name)
    doc = {"problem": {**p.__dict__, "stores": list(p.stores), "held_out": list(p.held_out)},
           "train": f["choice"]["rows"], "choice": {k: v for k, v in f["choice"].items()
                                                     if k != "rows"},
           "passes": {"search": r["search_passes"], "choice": r["choice_passes"]},
           "held_out": held, "model_db": f["model_db"],
           "held_out_vs_prototype": ({k: paired(held, k).get(name) for k in SCORES}
                                     if held else None),
           "evaluations": f["evaluations"], "setup_s": r["setup_s"],
           "search_s": f["curve"][-1][1], "curve": f["curve"],
           "light_model": {"prototype": light_of(r["problems"][0], r["base_code"]),
                           "prototype_capture": r["templates"][0].record.light_factor,
                           "found": light_of(r["problems"][0], f["code"])}}  # fmt: skip
    doc["store_noise"] = _store_noise(p, r["templates"])
    doc["design_focus_mm"] = float(f["design"].focus_distance_mm)
    write_report(out, doc, force, report_text(p, doc))
    write_patterns(out / "patterns.png", f["code"], name, force)
    return doc


def _store_noise(p: BitmapProblem, templates) -> list[float]:
    """Each training store's render noise over the sensor's (the captures the search scores),
    with a note where a store is noisier than a synthesised capture should be: designs are
    then ranked where render noise, not the camera's, dominates (``bench_bitmap_design.py``:
    at 1.5-2x the prototype lost 1-2 dB to it and fell behind designs it beats on direct
    renders)."""
    model = SensorModel.from_preset(p.sensor)
    got = [store_noise(t, model, p.light_level, p.sensor) for t in templates]
    for _, text in got:
        if text:
            note(text + "; the search ranks designs in that noise, not the camera's")
            break
    return [r for r, _ in got]


def check_still_loss(p: BitmapProblem, problems) -> None:
    """With ``max_still_loss_db``, some training store shows still pixels in the scorer's
    columns to hold it on."""
    if p.max_still_loss_db is None:
        return
    if not any(q.still.any() for q in problems):
        raise ParameterError("max_still_loss_db: no training store's window shows a still pixel "
                             "inside the scorer's columns")  # fmt: skip
