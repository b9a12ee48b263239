"""``pacam optimize``: design the aperture schedule for a speed and depth range."""

from __future__ import annotations

import argparse

from ..errors import ParameterError
from ..io.lock import output_lock
from ..io.outputs import prepare_out_dir
from ..lightfield.cell_basis import DEFAULT_CELLS
from ..limits import PacamWarning
from ..model.camera import preset
from ..model.design_file import resolve_design
from ..optimize.cell_objective import AGGREGATES, WORST_SOFTNESS_DB
from ..optimize.cell_run import (
    ITERATIONS,
    MAX_LEVELS,
    OBJECTIVES,
    STARTS,
    STILL_WEIGHT,
    BitmapProblem,
    check_bitmap_problem,
    run_bitmap_optimize,
)
from ..optimize.cell_search import LIGHT_CHOICES
from ..optimize.rendered import DEFAULT_METHOD
from ..optimize.rendered_run import (
    CHECK_SEEDS,
    NOISE_DRAWS,
    POSITIONS,
    SWEEPS,
    RenderedProblem,
    open_stores,
    run_rendered_optimize,
)
from ..optimize.run import run_optimize
from ..optimize.search import DEFAULT_LIGHT_LEVEL, Problem, check_problem, reference_design
from .common import add_outputs, add_preset, new_folder

FOURIER_ONLY = ("depth_range", "n_patterns", "free_radius", "f_number", "r_px", "design",
                "quick", "max_velocity")  # fmt: skip
"""Flags of the Fourier objective that a search on stores does not take (its camera is the
stores')."""
CELLS_FLAGS = ("cells", "light", "starts", "iterations", "objective", "still_weight", "held_out",
               "max_still_loss", "held_passes", "aggregate", "focus")  # fmt: skip
SPACE_FLAGS = {"centres": ("positions", "sweeps", "check_seeds"),
               "bitmap": CELLS_FLAGS + ("levels",),
               "discs": CELLS_FLAGS + ("lcos_switching",)}  # fmt: skip
"""Flags that only some ``--space`` of a search on stores takes: the ones each space takes."""
SPACES = tuple(SPACE_FLAGS)


def add(sub) -> None:
    p = sub.add_parser("optimize", help="design the aperture schedule for a speed/depth range")
    p.add_argument(
        "--max-velocity",
        type=float,
        metavar="PX_PER_MS",
        help="cover speeds |s| <= this, px/ms of the preset's sensor (the Fourier objective; "
        "required without --lightfield)",
    )
    _add_lightfield(p)
    p.add_argument(
        "--sensor",
        default="grasshopper-icx285",
        help="sensor noise preset (default grasshopper-icx285; paper: sigma 0.01)",
    )
    p.add_argument(
        "--n-patterns", type=int, metavar="N", help="default: the design's (the preset's: 16)"
    )
    p.add_argument(
        "--free-radius",
        action="store_true",
        help="also choose the opening's radius (light counted through the noise)",
    )
    p.add_argument("--f-number", type=float, metavar="N", help="the parabola's opening")
    p.add_argument("--r-px", type=float, metavar="PX", help="the parabola's defocus radius")
    add_preset(p)
    p.add_argument(
        "--design",
        metavar="FILE",
        help="design the schedule for this camera (a design file) instead of --preset",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random starts (default 0)")
    p.add_argument(
        "--starts",
        type=int,
        metavar="K",
        help=f"local searches (default 6; quick 2; --space bitmap: {STARTS}, the store's design "
        "and random codes)",
    )
    p.add_argument(
        "--iterations",
        type=int,
        metavar="I",
        help=f"L-BFGS-B iterations per start (default 100; quick 30; --space bitmap: Adam steps "
        f"per start, default {ITERATIONS})",
    )
    p.add_argument("--quick", action="store_true", help="a coarse grid, 2 short starts")
    add_outputs(p)
    p.set_defaults(func=run)  # fmt: skip


def _add_lightfield(p) -> None:
    """The flags of a search on light-field stores (``--lightfield``)."""
    p.add_argument(
        "--lightfield",
        nargs="+",
        metavar="STORE",
        help="search on rendered captures instead: light-field stores (pacam lightfield "
        "--uniform-share 1), one per scene or speed; the worst case over them is maximised",
    )
    p.add_argument(
        "--space",
        default="centres",
        help="with --lightfield: what is searched: centres (the openings' centres along x, "
        "coordinate search; default), bitmap (any binary LCoS bitmap on a grid of cells in "
        "each pattern window, gradient search) or discs (one disc per window, its centre in x "
        "and y, one radius, gradient search)",
    )
    _add_bitmap(p)
    _add_held_out(p)
    _add_centres(p)
    p.add_argument(
        "--noise-draws",
        type=int,
        default=NOISE_DRAWS,
        metavar="D",
        help=f"with --lightfield: sensor noise draws per evaluation (default {NOISE_DRAWS})",
    )
    p.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        help=f"with --lightfield: the deconvolver scored (default {DEFAULT_METHOD})",
    )
    p.add_argument("--depth-range", metavar="NEAR,FAR", help="mm (default: the preset's depth)")
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help="photons/px/ms of white through the full lens (default 300, the demo's)",
    )


def _add_bitmap(p) -> None:
    """The flags of ``--space bitmap`` (:mod:`~..optimize.cell_run`)."""
    p.add_argument(
        "--cells",
        type=int,
        metavar="G",
        help="with --space bitmap or discs: G x G cells over the clear aperture, G dividing "
        f"its 1024 LCoS pixels (default {DEFAULT_CELLS}, chosen by benchmarks/bench_cell_grid.py)",
    )
    p.add_argument(
        "--levels",
        type=int,
        metavar="N",
        help=f"with --space bitmap: transmittance levels per cell, 2 (binary, the prototype's "
        f"ferroelectric LCoS; default) to {MAX_LEVELS} (an LCoS that shows grey)",
    )
    p.add_argument(
        "--light",
        metavar="RULE",
        help="with --space bitmap or discs: the code's total light (open area x time): fixed at "
        "the store design's (default) or free (discs: the radius moves)",
    )
    p.add_argument(
        "--objective",
        metavar="WHAT",
        help=f"with --space bitmap or discs: what the model scores: {' or '.join(OBJECTIVES)} (the "
        "moving objects' PSNR, default; or its weighted mean in dB with the still pixels')",
    )
    p.add_argument(
        "--still-weight",
        type=float,
        metavar="W",
        help="with --objective moving+still: the still PSNR's weight w in (moving + w still) "
        f"/ (1 + w), > 0 (default {STILL_WEIGHT:g})",
    )
    p.add_argument(
        "--aggregate",
        metavar="HOW",
        help=f"with --space bitmap or discs: how the score is pooled over the training stores: "
        f"{' or '.join(AGGREGATES)} (their mean, default; or the soft minimum, tau "
        f"{WORST_SOFTNESS_DB:g} dB, of each store's gain over the store's own design)",
    )
    p.add_argument(
        "--focus",
        type=float,
        nargs="+",
        metavar="MM",
        help="with --space bitmap or discs: further focus distances to search at, mm, each "
        "from the store's design refocused there (within the stores' margin); the written "
        "design keeps the focus it was found at (default: the store design's focus only)",
    )


def _add_held_out(p) -> None:
    """``--held-out``: stores of scenes the search never sees, scored in the report; and
    ``--max-still-loss``, the constraint the choice holds on the training stores."""
    p.add_argument(
        "--held-passes",
        type=int,
        metavar="K",
        help="with --space bitmap or discs: the last K passes of each store are not searched "
        "on; the choice among the search's results is made on them, so that the search's fit "
        "to its samples' noise does not choose (default: half of them where every store has "
        "at least 4 passes, else 0: choose on the searched samples); 0 or 2 to passes - 2",
    )
    p.add_argument(
        "--lcos-switching",
        type=float,
        metavar="MS",
        help="with --space discs: the LCoS's switching time, ms (default 0): in the first MS "
        "of each pattern's window the pixels turn linearly from the previous pattern, in the "
        "search's basis and kernel and in every capture it scores",
    )
    p.add_argument(
        "--max-still-loss",
        type=float,
        metavar="DB",
        help="with --space bitmap or discs: a found design whose still regions lose more than "
        "DB dB against the store's design on the training stores (real pipeline) is not chosen "
        "(default: no limit); where none is eligible and better, the store's design is kept",
    )
    p.add_argument(
        "--held-out",
        nargs="+",
        metavar="STORE",
        help="with --space bitmap or discs: light-field stores of other scenes (the same "
        "camera), never searched on; the report scores the prototype and the found design on "
        "them with paired 95 %% intervals (at least 2)",
    )


def _add_centres(p) -> None:
    """The flags of ``--space centres`` (:mod:`~..optimize.rendered_run`)."""
    p.add_argument(
        "--positions",
        type=int,
        metavar="J",
        help=f"with --lightfield: candidate centres over the lens (default {POSITIONS})",
    )
    p.add_argument(
        "--sweeps",
        type=int,
        metavar="S",
        help=f"with --lightfield: sweeps over the patterns at most (default {SWEEPS})",
    )
    p.add_argument(
        "--check-seeds",
        type=int,
        metavar="K",
        help=f"with --lightfield: fresh renders per store and design that check the result "
        f"(default {CHECK_SEEDS}; 0 skips the check)",
    )


def run(args: argparse.Namespace) -> int:
    if args.lightfield:
        return _run_lightfield(args)
    for name in ("cells", "light", "levels", "positions", "sweeps", "check_seeds", "objective",
                 "still_weight", "aggregate", "focus"):  # fmt: skip
        if getattr(args, name) is not None:
            raise ParameterError(f"--{name.replace('_', '-')}: only a search with --lightfield "
                                 "takes it")  # fmt: skip
    if args.space != "centres":
        raise ParameterError("--space: only a search with --lightfield takes it")
    if args.max_velocity is None:
        raise ParameterError("--max-velocity is required (or search stores with --lightfield)")

    problem = Problem(
        max_velocity_px_per_ms=args.max_velocity,
        depth_range_mm=_depth_range(args.depth_range, args.preset, args.design),
        n_patterns=_n_patterns(args.n_patterns, args.preset, args.design),
        sensor=args.sensor,
        light_level=args.light_level,
        preset=args.preset,
        f_number=args.f_number,
        r_px=args.r_px,
        free_radius=args.free_radius,
        design=args.design,
    )
    check_problem(problem)
    reference_design(problem)  # the parabola must cover the range: refused before any output
    for flag in ("starts", "iterations"):
        v = getattr(args, flag)
        if v is not None and (v < 1):
            raise ParameterError(f"--{flag} must be an integer >= 1, got {v!r}")
    if not 0 <= args.seed < 2**32:
        raise ParameterError(f"--seed must be an integer in [0, 2^32), got {args.seed!r}")
    out = prepare_out_dir(args.out, args.force)
    with new_folder(out), output_lock(out):  # an interrupt before any file leaves no folder
        doc = run_optimize(problem, out, quick=args.quick, seed=args.seed, force=args.force,
                           starts=args.starts, iterations=args.iterations,
                           progress=not args.quiet)  # fmt: skip
    print((out / "report.md").read_text())
    gain = doc["objective_worst"] - doc["parabola_objective_worst"]
    print(f"worst-case gain over the parabola at equal light: {gain:+.2f} dB (predicted)")
    print(
        f"written: {out / 'design.toml'} (pacam render/psf/validate-psf --design), "
        f"schedule.json, report.md, 4 plots, lcos/ ({doc['n_patterns']} PNG)"
    )
    return 0


def _n_patterns(n: int | None, preset_name: str, design: str | None) -> int:
    """--n-patterns, else the design file's (or the preset's) own count: a 32-pattern design
    was optimised as 16 patterns, with no word."""
    if n is not None:
        return n
    if design is not None:
        return resolve_design(design).n_patterns
    return preset(preset_name).n_patterns


def _depth_range(text: str | None, preset_name: str, design: str | None) -> tuple[float, float]:
    if text is None:
        if design is not None:
            d = resolve_design(design).object_depth_mm
        else:
            d = preset(preset_name).object_depth_mm
        return d, d
    try:
        near, far = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError(f"--depth-range must be NEAR,FAR in mm, got {text!r}") from None
    return near, far


def _run_lightfield(args: argparse.Namespace) -> int:
    """``--lightfield``: the schedule searched on rendered captures (:mod:`..optimize.rendered`)."""
    import warnings

    for name in FOURIER_ONLY:
        if getattr(args, name) not in (None, False):
            raise ParameterError(
                f"--{name.replace('_', '-')}: a search on light-field stores takes the stores' "
                "camera and speeds; leave it out"
            )
    if not 0 <= args.seed < 2**32:
        raise ParameterError(f"--seed must be an integer in [0, 2^32), got {args.seed!r}")
    space = _space_flags(args)
    level = DEFAULT_LIGHT_LEVEL if args.light_level is None else args.light_level
    if space != "centres":
        return _run_bitmap(args, level)
    problem = RenderedProblem(
        stores=tuple(args.lightfield), sensor=args.sensor, light_level=level,
        positions=_or(args.positions, POSITIONS), sweeps=_or(args.sweeps, SWEEPS),
        noise_draws=args.noise_draws, method=args.method, seed=args.seed,
        check_seeds=_or(args.check_seeds, CHECK_SEEDS),
    )  # fmt: skip
    open_stores(problem)  # refused before any output
    out = prepare_out_dir(args.out, args.force)
    show, seen = warnings.showwarning, set()

    def once(message, category, *rest, **kw):  # each store and fresh render repeats its notes
        if issubclass(category, PacamWarning) and str(message) in seen:
            return
        seen.add(str(message))
        show(message, category, *rest, **kw)

    warnings.showwarning = once
    try:
        with new_folder(out), output_lock(out):
            doc = run_rendered_optimize(problem, out, args.force, progress=not args.quiet)
    finally:
        warnings.showwarning = show
    print((out / "report.md").read_text())
    print(f"written: {out / 'design.toml'} (pacam render/psf/validate-psf --design), "
          "search.json, search.png, report.md")  # fmt: skip
    return 0 if doc else 1


def _or(value, default):
    return default if value is None else value


def _space_flags(args: argparse.Namespace) -> str:
    """``--space``, checked, with the flags only the other space takes refused."""
    if args.space not in SPACES:
        raise ParameterError(f"--space: one of {', '.join(SPACES)}, got {args.space!r}")
    for name in dict.fromkeys(n for names in SPACE_FLAGS.values() for n in names):
        takes = [sp for sp, names in SPACE_FLAGS.items() if name in names]
        if args.space not in takes and getattr(args, name) is not None:
            raise ParameterError(
                f"--{name.replace('_', '-')}: only a search with --space {' or '.join(takes)} "
                "takes it"
            )
    cells = args.space != "centres"
    if cells and args.light is not None and args.light not in LIGHT_CHOICES:
        raise ParameterError(f"--light: one of {', '.join(LIGHT_CHOICES)}, got {args.light!r}")
    if cells and args.method != DEFAULT_METHOD:
        raise ParameterError(f"--method: a {args.space} search scores with {DEFAULT_METHOD} only")
    return args.space


def _run_bitmap(args: argparse.Namespace, level: float) -> int:
    """``--space bitmap`` or ``discs``: :func:`~..optimize.cell_run.run_bitmap_optimize`."""
    problem = BitmapProblem(
        stores=tuple(args.lightfield), sensor=args.sensor, light_level=level,
        cells=_or(args.cells, DEFAULT_CELLS), light=_or(args.light, "fixed"),
        levels=_or(args.levels, 2),
        starts=_or(args.starts, STARTS), iterations=_or(args.iterations, ITERATIONS),
        seed=args.seed, noise_draws=args.noise_draws,
        objective=_or(args.objective, "moving"), still_weight=args.still_weight,
        space=args.space, held_out=tuple(args.held_out or ()),
        max_still_loss_db=args.max_still_loss, held_passes=args.held_passes,
        lcos_switching_ms=args.lcos_switching, aggregate=_or(args.aggregate, "mean"),
        focus_mm=tuple(args.focus or ()),
    )  # fmt: skip
    check_bitmap_problem(problem)  # refused before any output
    out = prepare_out_dir(args.out, args.force)
    with new_folder(out), output_lock(out):
        run_bitmap_optimize(problem, out, args.force, progress=not args.quiet)
    print((out / "report.md").read_text())
    masks = " and design.masks.npz" if args.space == "bitmap" else ""
    print(f"written: {out / 'design.toml'}{masks} (pacam render --design), report.json, "
          "report.md, report.png, patterns.png")  # fmt: skip
    return 0
