"""A study's ``report.md`` and plots, written from ``results.csv`` (so a resumed or partly failed
study reports everything finished so far).

* light level x speed with several cameras (``crossover``, Fig. 8 rendered): a map of the
  winning camera per light level and speed, with its margin and where it is not resolved
  (:mod:`.crossover_map`).
* ``crossover``: PSNR of the moving objects against light level as small multiples, one panel
  per camera and speed (:mod:`.small_multiples`); and the light levels at which each coded
  capture overtakes the short and the normal exposure.
* ``speed`` (Fig. 6 rendered): PSNR of the moving objects against their speed, one line per
  capture.
* every report: a table of all points.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..io.outputs import save_figure, write_text
from ..model.camera import preset
from .crossover_map import map_applies, map_section, write_map
from .paired import paired_section
from .results import RESULTS, read_csv
from .small_multiples import curves_section, mode_curves, write_curves
from .spec import StudySpec

NUMERIC = (
    "speed_px_per_ms", "depth_mm", "light_level_photons_per_px_per_ms", "psnr_db", "ssim",
    "psnr_moving_db", "psnr_static_db", "psnr_moving_interior_db", "r_px", "a_i_px_per_ms2",
    "velocity_range_px_per_ms", "exposure_ms", "noise_sigma", "render_noise_sigma",
    "render_noise_ratio", "sharp_noise_sigma", "model_sigma", "deconv_sigma", "render_spp",
    "render_s", "total_s", "psnr_moving_no_model_sigma_db", "psnr_moving_floor_db",
    "psnr_moving_exact_model_db", "psnr_moving_oracle_db",
)  # fmt: skip
LIGHT = "light_level_photons_per_px_per_ms"


def load_rows(out: Path) -> list[dict]:
    """The rows of ``out/results.csv``, numbers as floats (nan where empty)."""
    rows = read_csv(out / RESULTS)
    for r in rows:
        for k in NUMERIC:
            r[k] = _number(r.get(k))
    return rows


def _number(cell) -> float:
    """A cell as a float; nan where it is empty or not a number (a damaged file is reported
    on, not crashed on; the study re-runs such rows, :func:`.results.row_is_intact`)."""
    try:
        return float(cell) if cell not in (None, "") else math.nan
    except (TypeError, ValueError):
        return math.nan


def label(row: dict, designs: int) -> str:
    """A capture's name in plots: its mode, its design when the study has several, its method."""
    text = row["mode"] + (f" {row['design']}" if designs > 1 else "")
    return text + ("" if row["method"] == "none" else f" + {row['method']}")


def curves(rows: list[dict], x: str, y: str, panel: str | None = None) -> dict:
    """{panel value: {label: (xs, mean ys over seeds)}} of the rows with status ok."""
    return {
        p: {lab: (xs, ys) for lab, (xs, ys, _) in c.items()}
        for p, c in curves_ci(rows, x, y, panel).items()
    }


def curves_ci(rows: list[dict], x: str, y: str, panel: str | None = None) -> dict:
    """{panel value: {label: (xs, mean ys, 95 % half-widths)}} over the seeds of the rows with
    status ok; the half-width is Student's t_{n-1} s / sqrt(n), 0 for a single seed."""
    from scipy.stats import t as student

    designs = len({r["design"] for r in rows})
    acc: dict = defaultdict(lambda: defaultdict(lambda: defaultdict(list)))
    for r in rows:
        if r["status"] == "ok":
            acc[r[panel] if panel else ""][label(r, designs)][r[x]].append(r[y])

    def half(v: list) -> float:
        n = len(v)
        return float(student.ppf(0.975, n - 1) * np.std(v, ddof=1) / np.sqrt(n)) if n > 1 else 0.0

    return {
        p: {
            lab: (
                np.array(sorted(d)),
                np.array([np.mean(d[k]) for k in sorted(d)]),
                np.array([half(d[k]) for k in sorted(d)]),
            )
            for lab, d in c.items()
        }
        for p, c in acc.items()
    }


def crossings(xs: np.ndarray, a: np.ndarray, b: np.ndarray) -> list[float]:
    """Where curve a crosses curve b (both at ``xs``), interpolated on log x."""
    d = a - b
    out = []
    for i in range(len(xs) - 1):
        if d[i] == 0:
            out.append(float(xs[i]))
        elif d[i] * d[i + 1] < 0:
            lx = np.log(xs[i]) + (np.log(xs[i + 1]) - np.log(xs[i])) * d[i] / (d[i] - d[i + 1])
            out.append(float(np.exp(lx)))
    return out


def write_report(spec: StudySpec, out: Path) -> list[str]:
    """``report.md`` and the study's plots in ``out``; returns the file names written.

    The report opens with what ran, derived from ``spec`` (window, sensor size and binning,
    samples, grid, seeds) and from the rows (the spp the renders took). For a ``--quick`` spec
    (``spec.quick``) the title and the plots say so, and the study's own description, which is
    of the full run, follows as such.

    Parameters
    ----------
    spec : StudySpec
        The study that ran (:func:`~.spec.load_study`, with ``quick`` as it ran).
    out : pathlib.Path
        Its results folder, holding ``results.csv``.

    Returns
    -------
    list of str
        The names of the files the study's folder now holds: ``results.csv``, ``report.md``
        and the plots.
    """
    rows = load_rows(out)
    ok = [r for r in rows if r["status"] == "ok"]
    oracle = ORACLE_TITLE if spec.model_error == "oracle" else ""
    head = f"# Study `{spec.name}`" + (" (quick)" if spec.quick else "") + oracle
    files, text = [], [head, ""]
    if spec.quick:
        text += [
            f"**A quick run** (`pacam study {spec.source or spec.name} --quick`): the study's "
            "small version, which checks that every step runs; its numbers are not the full "
            "study's. What ran:",
            "",
            _setup(spec, rows, ok),
            "",
            "The full study (without `--quick`), which this run is not:",
            "",
            *("> " + line if line else ">" for line in spec.description.strip().splitlines()),
            "",
        ]
    else:
        text += [spec.description.strip(), "", _setup(spec, rows, ok), ""]
    title = plot_title(spec)
    if ok and map_applies(ok):  # light level x speed with several cameras
        files.append(write_map(out, ok, title))
        text += map_section(ok)
    if spec.report == "crossover" and ok and mode_curves(ok):
        files.append(write_curves(out, ok, title))
        text += curves_section(ok)
        text += _crossover_text(ok)
    elif spec.report == "crossover" and ok:  # no moving object scored: no curves to draw
        text += ["No point scored a moving object (too few visible pixels, or none moves): "
                 "the crossover curves are not drawn.", ""]  # fmt: skip
    if spec.report == "speed" and ok:
        for y, name in (("psnr_moving_db", "speed"), ("psnr_moving_interior_db", "speed_interior")):
            data = curves_ci(ok, "speed_px_per_ms", y, LIGHT)
            xlabel = "speed of the moving object (px/ms, preset pixels)"
            files.append(_plot(out, f"{name}.png", data, xlabel, "light", False, _YLABEL[y], title))
            text += _speed_text(ok, y)
    if spec.render.get("lightfield"):
        text += paired_section(ok)
    text += _error_text(ok)
    text += _plateau_text(ok)
    text += ["## Every point", "", *_table(rows)]
    write_text(out / "report.md", "\n".join(text) + "\n", force=True)
    return ["results.csv", "report.md", *files]


def _setup(spec: StudySpec, rows: list[dict], ok: list[dict]) -> str:
    """What ran, from the spec that ran: window, sensor, samples, grid, seeds and progress."""
    r = spec.render
    where = (
        f"a {r['crop'][2]}x{r['crop'][3]} px window at ({r['crop'][0]}, {r['crop'][1]}) of"
        if r["crop"]
        else "the whole frame of"
    )
    failed = len(rows) - len(ok)
    samples = (
        f"each render to a Monte Carlo sigma of at most {r['noise_ratio']:g}x the lowest "
        "sensor noise it feeds"
        if r.get("noise_ratio")
        else f"{r['spp']} spp"
    )
    samples += f" (`{r.get('sampler', 'independent')}`"
    spp = [x["render_spp"] for x in ok if not math.isnan(x["render_spp"])]
    if r.get("noise_ratio") and spp:
        lo, hi = min(spp), max(spp)
        samples += f"; the renders took {lo:.0f}" + ("" if lo == hi else f" to {hi:.0f}") + " spp"
    seeds = sorted({p.seed for p in spec.points})
    return (
        f"{where} a {r['width']}x{r['height']} px `{r['preset']}` sensor{_binning(r)}, "
        f"{samples}), sensor model `{r['sensor']}` unless "
        f"a point says otherwise; {_grid_text(spec)}; {len(rows)} of {len(spec.points)} "
        f"points done, {failed} failed; {len(seeds)} seed(s) "
        f"({', '.join(map(str, seeds))}), the plots show their mean and, with several, its "
        "95 % confidence interval. Scores are against each capture's own `sharp` layer; the "
        "moving objects' PSNR takes each object at its best horizontal shift (a "
        "motion-invariant PSF moves it by -s^2 / (2 a_i)). Speeds are in the preset's own "
        "pixels (px/ms of the full sensor). " + told_text(spec.model_error)
    )


ORACLE_TITLE = " (oracle: told each capture's model error)"
"""Added to an oracle study's report heading and plot titles."""


def told_text(model_error) -> str:
    """What the deconvolver is told, in words, for the report (``[study] model_error``)."""
    base = (
        "The deconvolver is told what a real user knows, as `pacam deconvolve` tells it: the "
        "sensor's noise (per pixel for hl and tv) and the render's measured Monte Carlo noise"
    )
    if model_error == "none":
        return base + ' (`model_error = "none"`).'
    if model_error == "oracle":
        return (
            base + ', and, **oracle** (`model_error = "oracle"`), each capture\'s own departure '
            "from the convolution model measured against its `sharp` layer (`model_sigma`, "
            "`pacam_render/restore/model_error.py`): no real camera knows its sharp image. "
            "Nor is it an upper bound: a larger sigma regularises the whole image, and on the "
            "train's moving edges it scored up to 1 dB below the default (the "
            "`crossover_optics` re-run)."
        )
    return (
        base + f", and a model error of {float(model_error):.4g} (white = 1) calibrated on "
        "another capture (`model_error`)."
    )


def _binning(render: dict) -> str:
    """How the study's sensor relates to its preset's: '' at full resolution, else the
    preset's size and the binning factor (each study pixel is that many preset pixels)."""

    try:
        full = preset(render["preset"])
    except ParameterError:  # an unknown preset: the spec's check names it, not the report
        return ""
    fx, fy = full.width_px / render["width"], full.height_px / render["height"]
    if fx == fy == 1:
        return " (full resolution)"
    return f" (the preset's {full.width_px}x{full.height_px} binned {fx:g}x{fy:g})"


_AXIS_WORDS = {
    "mode": ("mode", ""),
    "design": ("design", ""),
    "speed_px_per_ms": ("speed", " px/ms"),
    "depth_mm": ("depth", " mm"),
    "light_level": ("light level", " photons/px/ms"),
    "sensor": ("sensor", ""),
    "method": ("method", ""),
}


def _grid_text(spec: StudySpec) -> str:
    """The points' values per axis, e.g. 'mode coded, normal; light level 10, 300 ...'."""
    parts = []
    for axis, (name, unit) in _AXIS_WORDS.items():
        values = {getattr(p, axis) for p in spec.points}
        if axis == "sensor" and values == {spec.render["sensor"]}:
            continue  # said with the render's sensor model
        given = sorted(v for v in values if v is not None)
        text = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in given)
        text += unit if given else ""
        if None in values:
            text += (" and " if given else "") + "the scene's own"
        parts.append(f"{name} {text}")
    scenes = ", ".join(sorted({p.scene for p in spec.points}))
    return f"{len(spec.points)} points of scene {scenes}: " + "; ".join(parts)


def plot_title(spec: StudySpec) -> str:
    """The title over a study's plots.

    Parameters
    ----------
    spec : StudySpec
        The study that ran.

    Returns
    -------
    str
        ``study NAME``; for a ``--quick`` spec also that it is the quick run, its window,
        sensor size and seed count, and that it is not the full study.
    """
    oracle = ORACLE_TITLE if spec.model_error == "oracle" else ""
    if not spec.quick:
        return f"study {spec.name}{oracle}"
    r = spec.render
    sensor = f"{r['width']}x{r['height']} sensor"
    where = f"{r['crop'][2]}x{r['crop'][3]} px window of a {sensor}" if r["crop"] else sensor
    seeds = len({p.seed for p in spec.points})
    return (
        f"study {spec.name}, QUICK run (--quick): {where}, {seeds} "
        f"seed{'s' if seeds != 1 else ''}; not the full study{oracle}"
    )


def _error_text(ok: list[dict]) -> list[str]:
    """The error budget: render noise against the sensor's, and the model error, per mode."""
    if not ok or all(math.isnan(r["render_noise_ratio"]) for r in ok):
        return []
    lines = [
        "## Error budget",
        "",
        "White = 1. The render's Monte Carlo sigma over the sensor's (`render_noise_ratio`: "
        "the render adds its square to the point's noise variance), and the capture's measured "
        "model error (`model_sigma`; told the deconvolver only with `model_error = "
        '"oracle"`), by mode and light level (median over the points; largest ratio in '
        "brackets).",
        "",
        "| mode | light | sensor sigma | render sigma | ratio (max) | model sigma | render spp |",
        "|---|---|---|---|---|---|---|",
    ]
    groups = defaultdict(list)
    for r in ok:
        groups[(r["mode"], r[LIGHT])].append(r)
    for (mode, light), rs in sorted(groups.items()):
        fields = ("noise_sigma", "render_noise_sigma", "render_noise_ratio", "model_sigma")
        med = {k: float(np.nanmedian([r[k] for r in rs])) for k in (*fields, "render_spp")}
        worst = max(r["render_noise_ratio"] for r in rs)
        lines.append(
            f"| {mode} | {light:.4g} | {med['noise_sigma']:.2e} | {med['render_noise_sigma']:.2e} "
            f"| {med['render_noise_ratio']:.3f} ({worst:.3f}) | {med['model_sigma']:.4f} | "
            f"{med['render_spp']:.0f} |"
        )
    return lines + [""]


def _plateau_text(ok: list[dict]) -> list[str]:
    """What sets the moving objects' score at the two highest light levels (``decompose``)."""
    col = "psnr_moving_exact_model_db"
    rows = [r for r in ok if not math.isnan(r[col])]
    if not rows:
        return []
    top = sorted({r[LIGHT] for r in rows})[-2:]
    lines = [
        "## What sets the high-light plateau",
        "",
        "The moving objects' PSNR (dB, mean over seeds) as the study restores them (told the "
        "sensor's and the render's noise, and the model error only as `model_error` says), "
        "told no model error, told the old fixed floor of 0.02, with the capture replaced by "
        "the convolution model's prediction k * sharp under the same sensor noise, restored as "
        "the study restores it (`pacam_render/study/plateau.py`), and told each capture's own "
        "measured model error (**oracle**: no real camera knows it, and it is not an upper "
        "bound; blank for rows written before it). Diffraction: `in` the capture, or `out` "
        "with its measured size (RMS, white = 1), next to the model sigma it would otherwise "
        "join; blank for rows written before the optics columns.",
        "",
        "| mode | design | speed | method | light | study | no model sigma | floor 0.02 | "
        "exact model | oracle | model sigma | diffraction |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    groups = defaultdict(list)
    for r in rows:
        if r[LIGHT] in top:
            key = (r["mode"], r["design"], r["speed_px_per_ms"], r["method"], r[LIGHT])
            groups[key].append(r)
    for (mode, design, speed, method, light), rs in sorted(groups.items()):
        m = {k: np.mean([r[k] for r in rs]) for k in ("psnr_moving_db", *_PLATEAU)}
        oracle = np.mean([r.get(ORACLE_COLUMN, math.nan) for r in rs])
        lines.append(
            f"| {mode} | {design} | {speed:.3g} | {method} | {light:.4g} | "
            f"{m['psnr_moving_db']:.2f} | {m[_PLATEAU[0]]:.2f} | {m[_PLATEAU[1]]:.2f} | "
            f"{m[_PLATEAU[2]]:.2f} | {'' if math.isnan(oracle) else f'{oracle:.2f}'} | "
            f"{m['model_sigma']:.4f} | {diffraction_cell(rs)} |"
        )
    return lines + [""]


def diffraction_cell(rows: list[dict]) -> str:
    """``in``, ``out <size>`` (the mean measured RMS, white = 1), ``mixed`` or blank."""
    states = {str(r.get("diffraction") or "") for r in rows}
    if states == {"in"}:
        return "in"
    if states == {"out"}:
        sizes = [_float(r.get("diffraction_sigma")) for r in rows]
        sizes = [s for s in sizes if not math.isnan(s)]
        return f"out {np.mean(sizes):.2g}" if sizes else "out"
    return "" if states == {""} else "mixed"


def _float(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


ORACLE_COLUMN = "psnr_moving_oracle_db"
"""The moving objects' PSNR told each capture's own model error (with ``decompose``)."""
_PLATEAU = (
    "psnr_moving_no_model_sigma_db",
    "psnr_moving_floor_db",
    "psnr_moving_exact_model_db",
    "model_sigma",
)
_YLABEL = {
    "psnr_moving_db": "PSNR of the moving objects (dB)",
    "psnr_moving_interior_db": "PSNR of their interiors, no occlusion (dB)",
}


def _plot(
    out: Path,
    name: str,
    data: dict,
    xlabel: str,
    panel: str,
    log: bool,
    ylabel: str = "",
    title: str = "",
) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = sorted(data, key=lambda v: float(v) if v != "" else 0)
    fig, axes = plt.subplots(1, len(keys), figsize=(4.6 * len(keys) + 2.2, 4), squeeze=False)
    names = sorted({lab.split(" + ")[0] for key in keys for lab in data[key]})
    colour = dict(zip(names, plt.get_cmap("tab10").colors))  # one colour per capture
    for ax, key in zip(axes[0], keys):
        for lab, (xs, ys, ci) in sorted(data[key].items()):
            what, _, method = lab.partition(" + ")
            style = _METHOD_STYLE.get(method, ":")
            c = colour[what]
            ax.plot(xs, ys, style, color=c, marker="o" if "coded" in what else "s", label=lab, ms=4)
            if np.any(ci > 0):
                ax.fill_between(xs, ys - ci, ys + ci, color=c, alpha=0.2, lw=0)
        ax.set_xscale("log" if log else "linear")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel or _YLABEL["psnr_moving_db"])
        unit = _PANEL_UNITS.get(panel, "")
        ax.set_title(f"{panel} {float(key):.4g} {unit}".strip() if key != "" else "")
        ax.grid(alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, out / name, 90)
    return name


_METHOD_STYLE = {"hl": "-", "wiener": "--"}
"""Line style per restoration method (others dotted); colour is the capture."""
_PANEL_UNITS = {"speed": "px/ms", "light": "photons/px/ms"}


def _crossover_text(ok: list[dict]) -> list[str]:
    lines = ["## Where the coded camera wins", ""]
    for speed, cs in sorted(curves(ok, LIGHT, "psnr_moving_db", "speed_px_per_ms").items()):
        sigma = curves([r for r in ok if r["speed_px_per_ms"] == speed], LIGHT, "noise_sigma")[""]
        for lab, (xs, ys) in sorted(cs.items()):
            if not lab.startswith("coded"):
                continue
            method = lab.rsplit(" + ", 1)[-1] if " + " in lab else None
            for other in ("short", "normal"):
                match = [
                    k
                    for k in cs
                    if k.startswith(other) and (method is None or k.endswith(f" + {method}"))
                ]
                if not match:
                    continue
                ox, oy = cs[match[0]]
                common = np.intersect1d(xs, ox)
                a, b = ys[np.isin(xs, common)], oy[np.isin(ox, common)]
                lines.append(_crossing_line(speed, lab, match[0], common, a, b, sigma.get(lab)))
    return lines + [""]


def _crossing_line(speed, lab, other, xs, a, b, sigma) -> str:
    head = f"- speed {float(speed):.3g} px/ms, {lab} vs {other}: "
    cross = crossings(xs, a, b)
    if not cross:
        better = "better" if np.all(a > b) else "worse"
        return (
            head
            + f"{better} at every light level ({np.min(a - b):+.2f} to {np.max(a - b):+.2f} dB)"
        )
    parts = []
    for c in cross:
        s = ""
        if sigma is not None:  # the coded capture's noise there, interpolated on log-log
            at = np.exp(np.interp(np.log(c), np.log(sigma[0]), np.log(sigma[1])))
            s = f" (coded noise sigma {at:.4f})"
        parts.append(f"{c:.3g} photons/px/ms{s}")
    wins = "below" if a[0] > b[0] else "above"
    return head + f"crosses at {', '.join(parts)}; coded wins {wins} the first crossing"


def _speed_text(ok: list[dict], y: str) -> list[str]:
    lines = [f"## Flatness over speed: {_YLABEL[y]}", ""]
    for light, cs in sorted(curves(ok, "speed_px_per_ms", y, LIGHT).items()):
        for lab, (xs, ys) in sorted(cs.items()):
            lines.append(
                f"- light {float(light):.4g}, {lab}: {ys.min():.2f} to {ys.max():.2f} dB over "
                f"{xs.min():.3g} to {xs.max():.3g} px/ms (spread {ys.max() - ys.min():.2f} dB)"
            )
    return lines + [""]


def _table(rows: list[dict]) -> list[str]:
    cols = "point mode design speed light method r_px PSNR SSIM moving static s status".split()
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append(
            f"| {r['point']} | {r['mode']} | {r['design']} | {r['speed_px_per_ms']:.3g} | "
            f"{r[LIGHT]:.4g} | {r['method']} | {r['r_px']:.3g} | {r['psnr_db']:.2f} | "
            f"{r['ssim']:.3f} | {r['psnr_moving_db']:.2f} | {r['psnr_static_db']:.2f} | "
            f"{r['total_s']:.1f} | {r['status'][:60]} |"
        )
    return out
