"""Which camera wins at each light level and speed: the winner table behind a study's map
figure, and the map itself (``crossover_map.png``).

A *camera* is a capture mode (``coded``, ``normal``, ...). At each cell (speed, light level)
each camera is scored by its best capture there: the design and restoration method whose mean
score over the seeds is highest. The cell's winner is the camera with the highest such mean,
the runner-up the next; the margin is the difference of their means in dB. Each mean carries
the 95 % Student-t half-width over its seeds, ``t_{n-1} s / sqrt(n)`` (0 for one seed, as in
:func:`.report.curves_ci`); a cell is *unresolved* where the winner's interval and the
runner-up's overlap, ``mean_w - half_w <= mean_r + half_r``, and the map hatches it.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.outputs import save_figure

LIGHT = "light_level_photons_per_px_per_ms"
SPEED = "speed_px_per_ms"
SCORE = "psnr_moving_db"
MAP_FILE = "crossover_map.png"

MODE_COLOURS = {
    "coded": "#0072B2",
    "coded_continuous": "#56B4E9",
    "levin": "#009E73",
    "flutter": "#CC79A7",
    "normal": "#E69F00",
    "short": "#D55E00",
    "reference": "#999999",
}
"""One colour per camera (Okabe-Ito, readable with the common colour-vision deficiencies);
other modes take the next of ``tab10``."""

HATCH = "////"
"""The hatch of an unresolved cell (the winner's and runner-up's intervals overlap)."""


@dataclass(frozen=True)
class Score:
    """A camera's best capture at one cell: its mean score over the seeds (dB), the 95 %
    half-width of that mean, the seeds it has, and which capture it is (design + method)."""

    mean: float
    half: float
    seeds: int
    capture: str


@dataclass(frozen=True)
class Cell:
    """One cell of the map: where it is, every camera's best :class:`Score` there, and the
    winner, runner-up (None where one camera ran), margin (dB, nan without a runner-up) and
    whether their intervals overlap."""

    speed: float
    light: float
    scores: dict = field(hash=False)
    winner: str = ""
    runner_up: str | None = None
    margin_db: float = math.nan
    overlap: bool = False


def half_width(values) -> float:
    """The 95 % half-width of the mean of ``values``: Student's ``t_{n-1} s / sqrt(n)``, 0 for
    a single value."""
    from scipy.stats import t as student

    n = len(values)
    if n < 2:
        return 0.0
    return float(student.ppf(0.975, n - 1) * np.std(values, ddof=1) / np.sqrt(n))


SCENE_SPEED = -1.0
"""The speed key of points that keep the scene's own speeds (an empty ``speed_px_per_ms``)."""


def speed_key(value: float) -> float:
    """A row's speed as a cell key: the speed, or :data:`SCENE_SPEED` where it is nan."""
    return value if math.isfinite(value) else SCENE_SPEED


def speed_label(key: float) -> str:
    """A speed key in words: ``0.7`` or ``the scene's own``."""
    return "the scene's own" if key == SCENE_SPEED else f"{key:.3g}"


def usable(rows: list[dict], score: str = SCORE) -> list[dict]:
    """The rows a comparison takes: status ``ok``, a finite score, a finite positive light."""
    return [r for r in rows if r["status"] == "ok" and math.isfinite(r[score]) and r[LIGHT] > 0]


def capture_name(row: dict, designs: int) -> str:
    """A capture within its camera: its design where the camera has several, and its method."""
    name = row["design"]
    name = Path(name).stem if name.endswith(".toml") else name  # a design file by its stem
    parts = [name] if designs > 1 else []
    parts += [] if row["method"] in ("", "none") else [row["method"]]
    return " + ".join(parts) or row["mode"]


def cell_scores(rows: list[dict], score: str = SCORE) -> dict:
    """Every camera's best capture per cell.

    Parameters
    ----------
    rows : list of dict
        Rows of ``results.csv`` (:func:`.report.load_rows`: numbers as floats); only the
        :func:`usable` ones count.
    score : str, optional
        The column to compare (default the moving objects' PSNR).

    Returns
    -------
    dict
        ``{(speed, light): {mode: Score}}`` (speed: :func:`speed_key`); a mode's score is
        that of its capture (design and method) with the highest mean over the seeds, ties
        to the first name.
    """
    ok = usable(rows, score)
    designs = defaultdict(set)
    for r in ok:
        designs[r["mode"]].add(r["design"])
    acc = defaultdict(lambda: defaultdict(list))
    for r in ok:
        capture = capture_name(r, len(designs[r["mode"]]))
        acc[(speed_key(r[SPEED]), r[LIGHT])][(r["mode"], capture)].append(r[score])
    out: dict = defaultdict(dict)
    for cell, captures in acc.items():
        for (mode, capture), values in sorted(captures.items()):
            s = Score(float(np.mean(values)), half_width(values), len(values), capture)
            if mode not in out[cell] or s.mean > out[cell][mode].mean:
                out[cell][mode] = s
    return dict(out)


def winner_cells(rows: list[dict], score: str = SCORE) -> list[Cell]:
    """The map's cells: each camera's best score, the winner, the runner-up, the margin and
    whether the winner's and runner-up's 95 % intervals overlap.

    Parameters
    ----------
    rows : list of dict
        Rows of ``results.csv`` as :func:`.report.load_rows` reads them.
    score : str, optional
        The column to compare (default the moving objects' PSNR, dB).

    Returns
    -------
    list of Cell
        Sorted by speed, then light level. Cameras rank by mean score, ties by name.
    """
    cells = []
    for (speed, light), scores in sorted(cell_scores(rows, score).items()):
        ranked = sorted(scores, key=lambda m: (-scores[m].mean, m))
        if len(ranked) == 1:
            cells.append(Cell(speed, light, scores, winner=ranked[0]))
            continue
        w, r = scores[ranked[0]], scores[ranked[1]]
        overlap = w.mean - w.half <= r.mean + r.half
        cells.append(Cell(speed, light, scores, ranked[0], ranked[1], w.mean - r.mean, overlap))
    return cells


def map_applies(rows: list[dict]) -> bool:
    """Whether a study's rows make a light level x speed map worth drawing: several cameras
    compared at one cell at least, over several light levels, with the sensor fixed and one
    scene and depth per speed row (one scene, or several at their own speeds and depths:
    held-out scenes of a family, each a row, :func:`row_scenes`)."""
    ok = usable(rows)
    fixed = {r["sensor"] for r in ok}
    lights = {r[LIGHT] for r in ok}
    compared = any(len(s) > 1 for s in cell_scores(ok).values())
    one_each = all(len(v) == 1 for v in _scenes_by_speed(ok).values())
    return len(fixed) == 1 and one_each and len(lights) > 1 and compared


def _scenes_by_speed(rows: list[dict]) -> dict:
    """Each speed row's (scene, depth) pairs."""
    out = defaultdict(set)
    for r in rows:
        out[speed_key(r[SPEED])].add((r["scene"], str(r["depth_mm"])))
    return out


def row_scenes(rows: list[dict]) -> dict:
    """Each speed row's scene, where the map's rows are several scenes (else empty)."""
    by = _scenes_by_speed(usable(rows))
    if len({s for v in by.values() for s, _ in v}) < 2:
        return {}
    return {k: next(iter(v))[0] for k, v in sorted(by.items())}


def mode_colour(mode: str, modes: list[str]) -> str:
    """A camera's colour: :data:`MODE_COLOURS`, else the next ``tab10`` colour by its place in
    ``modes``."""
    import matplotlib

    if mode in MODE_COLOURS:
        return MODE_COLOURS[mode]
    colours = matplotlib.colormaps["tab10"].colors
    return matplotlib.colors.to_hex(colours[sorted(modes).index(mode) % len(colours)])


def edges(values: list[float]) -> np.ndarray:
    """Cell edges around sorted positive ``values`` on a log axis: halfway (geometrically)
    between neighbours, the outer ones as far out as the nearest inner one (a single value:
    x/÷ 1.5)."""
    v = np.log(np.asarray(values, float))
    if len(v) == 1:
        return np.exp([v[0] - np.log(1.5), v[0] + np.log(1.5)])
    mid = (v[1:] + v[:-1]) / 2
    return np.exp(np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]]))


def map_caption(seeds: int) -> str:
    """What to read from the map, for its title and the report's caption."""
    ci = (
        f"hatched: their 95 % intervals over {seeds} seeds overlap, the win is not resolved"
        if seeds > 1
        else "one seed: no intervals, so nothing is hatched"
    )
    return (
        "Which camera restores the moving objects best? Colour: the winning camera (at its "
        "best design and method); number: its PSNR margin over the runner-up camera (dB); "
        f"{ci}"
    )


def map_figure(cells: list[Cell], title: str = ""):
    """The map: light level (log) across, speed up; each cell coloured by its winner, with
    the margin, the winning capture and the runner-up written in it, hatched where the
    intervals overlap.

    Parameters
    ----------
    cells : list of Cell
        :func:`winner_cells`.
    title : str, optional
        The study's title (:func:`.report.plot_title`), put above the map's caption.

    Returns
    -------
    matplotlib.figure.Figure
        One axes; each cell's rectangle has the gid ``cell SPEED LIGHT`` (:func:`speed_label`,
        ``%g``), its margin
        text ``margin SPEED LIGHT`` and its small print ``detail SPEED LIGHT``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lights = sorted({c.light for c in cells})
    speeds = sorted({c.speed for c in cells})
    xe, ye = edges(lights), np.arange(len(speeds) + 1) - 0.5  # a row per speed
    fig, ax = plt.subplots(figsize=(max(8.0, 1.3 * len(lights) + 3.4), 1.0 * len(speeds) + 2.4))
    modes = sorted({m for c in cells for m in c.scores})
    for c in cells:
        _draw_cell(ax, c, xe, ye, lights.index(c.light), speeds.index(c.speed), modes)
    ax.set_xscale("log")
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xticks(lights, [f"{v:g}" for v in lights])
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.set_yticks(range(len(speeds)), [speed_label(v) for v in speeds])
    ax.set_xlabel("light level (photons/px/ms, white, F2.8; log)")
    ax.set_ylabel("object speed (px/ms)")
    _map_legend(ax, cells, modes)
    seeds = max((s.seeds for c in cells for s in c.scores.values()), default=1)
    caption_title(fig, title, map_caption(seeds).replace("? ", "?\n", 1))
    return fig


def caption_title(fig, title: str, caption: str) -> None:
    """Put ``title`` (one line) over ``caption`` (wrapped to the figure's width) as the
    figure's suptitle, and lay the figure out."""
    import textwrap

    width = int(fig.get_figwidth() * 15)  # characters of 8.5 pt text per line
    lines = [textwrap.fill(p, width) for p in caption.split("\n")]
    fig.suptitle("\n".join(([title] if title else []) + lines), fontsize=8.5)
    fig.tight_layout()


def _draw_cell(ax, c: Cell, xe, ye, i: int, j: int, modes: list[str]) -> None:
    """One cell: a rectangle in the winner's colour (hatched where unresolved) and its text."""
    from matplotlib.patches import Rectangle

    gid = f"{speed_label(c.speed)} {c.light:g}"
    rect = Rectangle(
        (xe[i], ye[j]),
        xe[i + 1] - xe[i],
        ye[j + 1] - ye[j],
        facecolor=mode_colour(c.winner, modes),
        edgecolor="white",
        linewidth=1.5,
        hatch=HATCH if c.overlap else None,
        gid=f"cell {gid}",
    )
    ax.add_patch(rect)
    at = (math.sqrt(xe[i] * xe[i + 1]), (ye[j] + ye[j + 1]) / 2)
    box = {"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.85}
    head = {"fontsize": 10, "fontweight": "bold", "va": "bottom", "gid": f"margin {gid}"}
    small = {"fontsize": 6.5, "va": "top", "gid": f"detail {gid}"}
    for text, offset, style in ((margin_text(c), 1, head), (detail_text(c), -1, small)):
        ax.annotate(
            text, at, xytext=(0, offset), textcoords="offset points", ha="center", bbox=box, **style
        )


def margin_text(c: Cell) -> str:
    """The cell's headline: the margin in dB (``only MODE`` without a runner-up)."""
    return f"only {c.winner}" if c.runner_up is None else f"{c.margin_db:+.1f} dB"


def detail_text(c: Cell) -> str:
    """The cell's small print: the winning capture, and over which camera."""
    w = c.scores[c.winner]
    return f"{c.winner} {w.capture}" + (f"\nover {c.runner_up}" if c.runner_up else "")


def _map_legend(ax, cells: list[Cell], modes: list[str]) -> None:
    """One patch per camera that wins a cell somewhere (others listed as never winning), and
    the hatch."""
    from matplotlib.patches import Patch

    winners = sorted({c.winner for c in cells})
    handles = [Patch(facecolor=mode_colour(m, modes), label=f"{m} wins") for m in winners]
    never = [m for m in modes if m not in winners]
    if never:
        handles.append(
            Patch(facecolor="none", edgecolor="none", label="never wins: " + ", ".join(never))
        )
    if any(c.overlap for c in cells):
        label = "intervals overlap"
        handles.append(Patch(facecolor="white", edgecolor="0.3", hatch=HATCH, label=label))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))


def write_map(out: Path, rows: list[dict], title: str = "") -> str:
    """Draw the map of ``rows`` (:func:`winner_cells`) to ``out/crossover_map.png``; returns
    the file's name."""
    save_figure(map_figure(winner_cells(rows), title), out / MAP_FILE, 110)
    return MAP_FILE


def map_table(cells: list[Cell]) -> list[str]:
    """The map as a markdown table: per cell the winner's capture and mean, the runner-up's,
    the margin and whether the intervals overlap."""
    lines = [
        "| speed (px/ms) | light (photons/px/ms) | winner | PSNR (dB) | runner-up | PSNR (dB) "
        "| margin (dB) | intervals overlap |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in cells:
        w = c.scores[c.winner]
        r = c.scores.get(c.runner_up) if c.runner_up else None
        other = f"{c.runner_up} {r.capture} | {_pm(r)}" if r else "- | -"
        lines.append(
            f"| {speed_label(c.speed)} | {c.light:g} | {c.winner} {w.capture} | {_pm(w)} | "
            f"{other} | {c.margin_db:+.2f} | {'yes' if c.overlap else 'no'} |"
        )
    return lines


def map_section(rows: list[dict], name: str = MAP_FILE) -> list[str]:
    """The report's section on the map: the figure, a caption that says what to read from
    it, and the table behind it."""
    cells = winner_cells(rows)
    seeds = max((s.seeds for c in cells for s in c.scores.values()), default=1)
    return [
        "## Which camera wins",
        "",
        f"![Which camera wins at each light level and speed]({name})",
        "",
        f"*Figure: {map_caption(seeds)}. Light level across (log), object speed up. Read a "
        "column for how the winner changes with speed at one light level, a row for the "
        "light level at which one camera takes over from another. Each camera is scored "
        "by its best capture in the cell (design and method, named in the cell), by the "
        "moving objects' PSNR (mean over the seeds).*",
        "",
        *map_table(cells),
        "",
        *_scene_lines(rows),
    ]


def _scene_lines(rows: list[dict]) -> list[str]:
    """Which scene each speed row is, where the rows are several scenes."""
    scenes = row_scenes(rows)
    if not scenes:
        return []
    return [
        "Each speed row is one scene at its own speeds (its fastest moving object's): "
        + "; ".join(f"{speed_label(k)} px/ms: {v}" for k, v in scenes.items())
        + ".",
        "",
    ]


def _pm(s: Score) -> str:
    return f"{s.mean:.2f} +- {s.half:.2f}" if s.seeds > 1 else f"{s.mean:.2f}"
