"""``pacam optimize --lightfield``: the schedule searched on rendered captures, then checked on
fresh renders.

The stores (one per scene or speed) share one camera, the base design they were rendered for.
The search keeps its radius, focus, exposure and pattern count and moves the n centres over a
grid of candidates (:mod:`.rendered`), maximising the worst case over the stores of the moving
objects' PSNR after the sensor and the deconvolver. The design it finds is then rendered
directly, beside the base design, with new render seeds and new sensor draws: a gain that
holds there is not the store's noise.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import ParameterError, check_integer
from ..exposure.direct import render_capture
from ..exposure.plan import plan_capture
from ..exposure.spec import CaptureSpec
from ..lightfield import Store
from ..lightfield.centre_basis import centre_basis
from ..lightfield.synthesis import store_noise_note, synthesize
from ..limits import available_bytes, gib, note
from ..model.design_file import write_design
from ..restore.deconvolve import METHODS, require_method
from ..sensor.apply import clean_level, sensor_sigma
from ..sensor.model import SensorModel
from .rendered import DEFAULT_METHOD, CaptureScorer, StoreObjective, coordinate_search
from .rendered_outputs import write_outputs
from .search import DEFAULT_LIGHT_LEVEL

POSITIONS = 17
"""Candidate centres spread evenly over the lens's reach, +-(R_max - R) (the base design's own
centres are added): 0.87 mm apart for the prototype, under half its opening's radius."""
SWEEPS = 3
"""Sweeps over the patterns at most (a sweep that moves nothing ends the search)."""
NOISE_DRAWS = 2
"""Sensor noise draws per evaluation (the same for every design)."""
CHECK_SEEDS = 3
"""Fresh renders per store and design in the check: a 95 % interval needs more than two."""
FRESH_SEED = 1000
"""The fresh renders' seeds start this far from the store's, and their sensor draws too."""


@dataclass(frozen=True)
class RenderedProblem:
    """What ``pacam optimize --lightfield`` searches: its stores and how it scores."""

    stores: tuple[str, ...]
    sensor: str = "grasshopper-icx285"
    light_level: float | None = DEFAULT_LIGHT_LEVEL
    positions: int = POSITIONS
    sweeps: int = SWEEPS
    noise_draws: int = NOISE_DRAWS
    method: str = DEFAULT_METHOD
    seed: int = 0
    check_seeds: int = CHECK_SEEDS


def base_spec(store):
    """The coded capture a store was rendered for (its scene, window, camera and samples)."""

    s = dict(store.manifest.capture)
    s["crop"] = tuple(s["crop"]) if s["crop"] else None
    return CaptureSpec(**{**s, "mode": "coded"})


CAMERA_KEYS = ("preset", "design", "cover_px_per_ms", "f_number", "r_px", "schedule",
               "object_depth_mm", "width", "height", "grey", "relative_illumination",
               "lcos_contrast")  # fmt: skip
"""The capture fields that make a store's camera: every store of a search must agree."""


def open_stores(p: RenderedProblem):
    """The stores, checked to share one camera, with the settings in range, before any work."""

    if not p.stores:
        raise ParameterError("stores: give at least one light-field store")
    for name, lo in (("positions", 2), ("sweeps", 1), ("noise_draws", 1), ("check_seeds", 0)):
        check_integer(f"`{name}`" if "_" not in name else name, getattr(p, name), lo, None)
    if p.method not in METHODS:
        raise ParameterError(f"method must be one of {', '.join(METHODS)}, got {p.method!r}")
    require_method(p.method)
    SensorModel.from_preset(p.sensor)
    stores = [Store.open(s) for s in p.stores]
    first = stores[0].manifest.capture
    for folder, st in zip(p.stores[1:], stores[1:]):
        other = st.manifest.capture
        for key in CAMERA_KEYS:
            if other[key] != first[key]:
                raise ParameterError(
                    f"stores: {folder} has {key} = {other[key]!r}, {p.stores[0]} has "
                    f"{first[key]!r}: the stores of one search share one camera"
                )
    check_positions_memory(p.positions, stores)
    return stores


def _note_store_noise(template, scorer, sensor: str) -> None:
    """Say when a store's render noise is a large share of the sensor's the search scores
    through (:func:`store_noise`)."""
    text = store_noise(template, scorer.model, scorer.light_level, sensor)[1]
    if text:
        note(text)


def store_noise(template, model, light_level, sensor: str) -> tuple[float, str | None]:
    """A store's capture's render noise over the sensor's noise it is scored through (at
    ``light_level``), and :func:`~pacam_render.lightfield.synthesis.store_noise_note`'s text
    where that exceeds the share a synthesised capture should stay under."""
    rec = template.record
    sigma = sensor_sigma(rec, model, light_level, clean_level(template)) * rec.light_factor
    light = "" if light_level is None else f" at {light_level:g} photons/px/ms"
    ratio = float(rec.render_error.mc_sigma / sigma) if sigma > 0 else float("nan")
    return ratio, store_noise_note(template, sigma, f"{sensor}{light}")


def basis_bytes(stores, n_patterns: int, candidates: int) -> float:
    """Peak memory of the stores' centre bases (:func:`~..lightfield.centre_basis.centre_basis`)
    for ``candidates`` centres, bytes: what grows with the candidates.

    Each store keeps n (J + 1) h w c float32 values; the one being built holds them twice more
    in float64 (the sums and the mean over passes), and each shard's sample-to-centre distances,
    rows x J float64 with their temporaries and mask (17 bytes a pair), besides its records.
    """
    kept, build = 0.0, 0.0
    for store in stores:
        cam = store.manifest.camera
        _, _, w, h = cam.window
        entries = store.manifest.channels * n_patterns * (candidates + 1) * w * h
        film = (w + 2 * cam.margin_px) * (h + 2 * cam.margin_px)
        rows = film * max(step.spp for steps in store.manifest.steps for step in steps)
        kept += 4.0 * entries
        build = max(build, 16.0 * entries + rows * (17.0 * candidates + 64.0))
    return kept + build


def check_positions_memory(positions: int, stores) -> None:
    """Refuse ``positions`` candidate centres whose centre bases would not fit in the memory
    available now, naming ``positions`` and the most that fit, before any store is read.

    Raises
    ------
    ParameterError
        If :func:`basis_bytes` at ``positions`` (and the base design's own n centres) exceeds
        :func:`~pacam_render.limits.available_bytes`.
    """
    n = len(plan_capture(base_spec(stores[0])).cam.pattern_centres_xy_mm())
    free = available_bytes()
    need = basis_bytes(stores, n, positions + n)
    if need <= free:
        return
    lo, hi = 1, positions  # the most that fit, by bisection (the need grows with positions)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if basis_bytes(stores, n, mid + n) <= free else (lo, mid - 1)
    most = f"at most {lo} fit" if lo >= 2 else "not even 2 fit"
    raise ParameterError(
        f"`positions` {positions}: the centre bases of {len(stores)} store(s) ({n} patterns x "
        f"{positions + n} centres) need about {gib(need)} of memory, and {gib(free)} is "
        f"available; {most}"
    )


def candidate_positions(cam, count: int) -> np.ndarray:
    """``count`` centres evenly over +-(R_max - R), and the base design's own (mm)."""
    reach = cam.R_max_mm - cam.R_mm
    own = cam.pattern_centres_xy_mm()[:, 0]
    return np.unique(np.concatenate([np.linspace(-reach, reach, count), own]))


def run_rendered_optimize(p: RenderedProblem, out: Path, force: bool, progress: bool) -> dict:
    """Search, check on fresh renders, and write design.toml, search.json, report.md and
    search.png into ``out``.

    Returns
    -------
    dict
        The search.json object.
    """

    stores = open_stores(p)
    specs = [base_spec(s) for s in stores]
    plan = plan_capture(specs[0])
    positions = candidate_positions(plan.cam, p.positions)
    t0 = time.perf_counter()
    seeds = tuple(range(p.noise_draws))
    objectives = []
    for store, spec in zip(stores, specs):
        template = synthesize(store, spec, progress=False)
        basis = centre_basis(store, spec, positions, progress)
        scorer = CaptureScorer(template, p.sensor, p.light_level, seeds, p.method)
        _note_store_noise(template, scorer, p.sensor)
        objectives.append(StoreObjective(basis, template, scorer))
    setup_s = time.perf_counter() - t0
    start = np.searchsorted(positions, plan.cam.pattern_centres_xy_mm()[:, 0])
    trace = coordinate_search(objectives, start, p.sweeps, p.seed, progress)
    found = found_design(plan, positions[trace.index])
    write_design(out / "design.toml", found, force)
    doc = _document(p, stores, positions, trace, objectives, start, setup_s)
    if p.check_seeds:
        doc["fresh"] = fresh_check(p, specs, out / "design.toml", progress)

    write_outputs(out, doc, force)
    return doc


def found_design(plan, centres_x_mm):
    """The base design at its full sensor size with the found centres."""
    d = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px)
    return d.with_(pattern_centres_mm=tuple((float(x), 0.0) for x in centres_x_mm),
                   pattern_masks=None, quoted_a_i_px_per_ms2=None,
                   name="pacam optimize --lightfield")  # fmt: skip


def _document(p, stores, positions, trace, objectives, start, setup_s: float) -> dict:
    start_per = [o.psnr_db(start) for o in objectives]
    return {
        "stores": [{"folder": str(f), "digest": s.digest, "scene": s.manifest.scene,
                    "window": list(s.manifest.camera.window)}
                   for f, s in zip(p.stores, stores)],  # fmt: skip
        "sensor": p.sensor, "light_level": p.light_level, "method": p.method,
        "noise_draws": p.noise_draws, "seed": p.seed, "positions_mm": positions.tolist(),
        "start_centres_mm": positions[start].tolist(),
        "found_centres_mm": positions[trace.index].tolist(),
        "start_psnr_moving_db": start_per, "found_psnr_moving_db": trace.per_store_db,
        "start_worst_db": min(start_per), "found_worst_db": trace.worst_db,
        "evaluations": trace.evaluations, "setup_s": setup_s,
        "trace": [list(r) for r in trace.rows],
        "scoring": "moving objects' PSNR against sharp after the sensor and a deconvolution "
                   "told the sensor's noise and the render's Monte Carlo noise (no oracle)",
    }  # fmt: skip


def fresh_check(p: RenderedProblem, specs, design_path: Path, progress: bool) -> dict:
    """The base and found designs rendered directly with new seeds, scored alike.

    Returns
    -------
    dict
        Per store: each design's PSNR per fresh seed; the paired difference's mean and 95 %
        interval; and the worst case over the stores per seed.
    """
    from scipy import stats

    rows = []
    per_seed = {k: np.zeros((len(specs), p.check_seeds)) for k in ("base", "found")}
    for i, spec in enumerate(specs):
        found = replace(spec, design=str(design_path), cover_px_per_ms=None, f_number=None,
                        r_px=None, schedule=None)  # fmt: skip
        for j in range(p.check_seeds):
            seed = spec.seed + FRESH_SEED + j
            for name, s in (("base", spec), ("found", found)):
                cap = render_capture(replace(s, seed=seed), progress=progress, truth=True)
                draws = tuple(FRESH_SEED + seed * 16 + d for d in range(p.noise_draws))
                scorer = CaptureScorer(cap, p.sensor, p.light_level, draws, p.method)
                per_seed[name][i, j] = scorer.psnr_db(cap)
        d = per_seed["found"][i] - per_seed["base"][i]
        rows.append({"scene": spec.scene, "window": list(spec.crop) if spec.crop else None,
                     "base_db": per_seed["base"][i].tolist(),
                     "found_db": per_seed["found"][i].tolist(), **_interval(d, stats)})  # fmt: skip
    worst = {k: v.min(axis=0) for k, v in per_seed.items()}  # per fresh seed, over the stores
    d = worst["found"] - worst["base"]
    return {"stores": rows, "worst": {"base_db": worst["base"].tolist(),
                                      "found_db": worst["found"].tolist(),
                                      **_interval(d, stats)}}  # fmt: skip


def _interval(d: np.ndarray, stats) -> dict:
    """The mean of paired differences and its 95 % t interval (None from one seed)."""
    n = len(d)
    mean = float(np.mean(d))
    if n < 2:
        return {"gain_db": mean, "gain_ci95_db": None}
    half = float(stats.t.ppf(0.975, n - 1) * np.std(d, ddof=1) / np.sqrt(n))
    return {"gain_db": mean, "gain_ci95_db": [mean - half, mean + half]}
