"""A study's score curves as small multiples (``crossover.png``): one panel per camera (columns)
and speed (rows), on shared axes, so that each panel holds a few curves, those of one camera's
captures, with the other cameras' best curves drawn faintly behind them for comparison."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from ..io.outputs import save_figure
from .crossover_map import (
    LIGHT,
    SCENE_SPEED,
    SCORE,
    SPEED,
    caption_title,
    capture_name,
    half_width,
    mode_colour,
    speed_key,
    speed_label,
    usable,
)

CURVES_FILE = "crossover.png"
METHOD_STYLE = {"hl": "-", "wiener": "--"}
"""Line style per restoration method (others dotted)."""
DESIGN_MARKERS = "os^Dv<>"


def mode_curves(rows: list[dict], score: str = SCORE) -> dict:
    """Each camera's capture curves per speed.

    Parameters
    ----------
    rows : list of dict
        Rows of ``results.csv`` (:func:`.report.load_rows`); only the
        :func:`.crossover_map.usable` ones count.
    score : str, optional
        The column drawn (default the moving objects' PSNR, dB).

    Returns
    -------
    dict
        ``{speed: {mode: {capture: (lights, means, 95 % half-widths)}}}`` (speed:
        :func:`.crossover_map.speed_key`), each over the seeds,
        lights sorted; a capture is named by its design (where the camera has several) and its
        method.
    """
    ok = usable(rows, score)
    designs = defaultdict(set)
    for r in ok:
        designs[r["mode"]].add(r["design"])
    acc = defaultdict(lambda: defaultdict(lambda: defaultdict(lambda: defaultdict(list))))
    for r in ok:
        capture = capture_name(r, len(designs[r["mode"]]))
        acc[speed_key(r[SPEED])][r["mode"]][capture][r[LIGHT]].append(r[score])
    return {
        speed: {
            mode: {cap: _curve(by_light) for cap, by_light in sorted(caps.items())}
            for mode, caps in sorted(modes.items())
        }
        for speed, modes in sorted(acc.items())
    }


def _curve(by_light: dict) -> tuple:
    xs = sorted(by_light)
    ys = [float(np.mean(by_light[x])) for x in xs]
    return np.array(xs), np.array(ys), np.array([half_width(by_light[x]) for x in xs])


def curves_figure(rows: list[dict], title: str = ""):
    """The small multiples: PSNR of the moving objects against light level (log), one column
    per camera and one row per speed, all panels on the same axes.

    Each panel draws its camera's captures in the camera's colour (marker: design, line:
    method), with their 95 % band over the seeds, and the other cameras' best capture at each
    light level as thin grey lines.

    Parameters
    ----------
    rows : list of dict
        Rows of ``results.csv`` as :func:`.report.load_rows` reads them.
    title : str, optional
        The study's title (:func:`.report.plot_title`), above the caption.

    Returns
    -------
    matplotlib.figure.Figure
        Axes ``[speed row][camera column]``, each with the gid ``panel MODE SPEED``
        (:func:`.crossover_map.speed_label`).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = mode_curves(rows)
    speeds = sorted(data)
    modes = sorted({m for d in data.values() for m in d})
    fig, axes = plt.subplots(
        len(speeds),
        len(modes),
        figsize=(2.7 * len(modes) + 0.8, 2.3 * len(speeds) + 1.4),
        sharex=True,
        sharey=True,
        squeeze=False,
    )
    floor = y_floor(data)
    for i, speed in enumerate(speeds):
        for j, mode in enumerate(modes):
            ax = axes[i][j]
            ax.set_gid(f"panel {mode} {speed_label(speed)}")
            _panel(ax, data[speed], mode, modes, floor)
            where = "the scene's own speeds" if speed == SCENE_SPEED else f"{speed:g} px/ms"
            ax.set_title(f"{mode}, {where}", fontsize=8, color=mode_colour(mode, modes))
    if floor is not None:
        axes[0][0].set_ylim(bottom=floor)
    _label_axes(axes)
    caption_title(fig, title, curves_caption(floor))
    return fig


def curves_caption(floor: float | None = None) -> str:
    """What to read from the small multiples, for their title and the report's caption
    (with ``floor``: where the y axis is cut)."""
    cut = (
        f"; points under {floor:g} dB are marked v on the bottom edge" if floor is not None else ""
    )
    return (
        "PSNR of the moving objects vs light level, one panel per camera and speed, shared "
        "axes: line = method, marker = design, band = 95 % interval over the seeds; "
        f"grey = the other cameras' best captures, for comparison{cut}"
    )


def y_floor(data: dict) -> float | None:
    """Where to cut the shared y axis: 2 dB below the lowest point of any camera's best
    curve (the losing captures under it are not what the figure compares), on a whole dB;
    None where no point lies below that."""
    best = [y for at in data.values() for caps in at.values() for y in _best(caps)[1]]
    every = [y for at in data.values() for caps in at.values() for c in caps.values() for y in c[1]]
    if not best:
        return None
    floor = float(np.floor(min(best) - 2))
    return floor if min(every) < floor else None


def _panel(ax, at_speed: dict, mode: str, modes: list[str], floor: float | None) -> None:
    """One camera's curves at one speed, over the other cameras' best ones in grey; points
    under ``floor`` drawn as v on it."""
    for other in sorted(at_speed):
        if other != mode:
            xs, ys = _best(at_speed[other])
            ax.plot(xs, ys, color="0.75", lw=0.8, zorder=1)
    colour = mode_colour(mode, modes)
    caps = at_speed.get(mode, {})
    designs = sorted({c.split(" + ")[0] for c in caps if " + " in c})
    for cap, (xs, ys, ci) in caps.items():
        design, _, method = cap.rpartition(" + ") if " + " in cap else ("", "", cap)
        marker = DESIGN_MARKERS[designs.index(design) % 7] if design in designs else "o"
        style = METHOD_STYLE.get(method, ":")
        ax.plot(xs, ys, style, color=colour, marker=marker, ms=3.5, lw=1.3, label=cap, zorder=3)
        if np.any(ci > 0):
            ax.fill_between(xs, ys - ci, ys + ci, color=colour, alpha=0.2, lw=0, zorder=2)
        if floor is not None and np.any(ys < floor):
            low = xs[ys < floor]
            ax.plot(low, np.full(len(low), floor), "v", color=colour, ms=5, clip_on=False)
    if caps:
        ax.legend(fontsize=6, loc="lower right")
    ax.set_xscale("log")
    ax.grid(alpha=0.3)


def _best(captures: dict) -> tuple:
    """The best mean over a camera's captures at each light level any of them has."""
    best: dict = {}
    for xs, ys, _ in captures.values():
        for x, y in zip(xs, ys):
            best[x] = max(best.get(x, -np.inf), y)
    xs = sorted(best)
    return np.array(xs), np.array([best[x] for x in xs])


def _label_axes(axes) -> None:
    """Axis labels on the outer panels only (the axes are shared)."""
    for ax in axes[-1]:
        ax.set_xlabel("light (photons/px/ms)", fontsize=8)
    for row in axes:
        row[0].set_ylabel("PSNR moving (dB)", fontsize=8)


def write_curves(out: Path, rows: list[dict], title: str = "") -> str:
    """Draw the small multiples of ``rows`` to ``out/crossover.png``; returns the file's name."""
    save_figure(curves_figure(rows, title), out / CURVES_FILE, 100)
    return CURVES_FILE


def curves_section(rows: list[dict], name: str = CURVES_FILE) -> list[str]:
    """The report's section on the small multiples: the figure and what to read from it."""
    floor = y_floor(mode_curves(rows))
    return [
        "## Each camera's curves",
        "",
        f"![PSNR of the moving objects against light level, per camera and speed]({name})",
        "",
        f"*Figure: {curves_caption(floor)}. Compare a panel's coloured "
        "curves with the grey ones behind them: where a coloured curve is on top, that camera wins "
        "(the map above says by how much); the spread of one panel's curves is what the "
        "design and the restoration method change.*",
        "",
    ]
