"""An honest report of designs scored with the real pipeline: each capture (synthesised from a
store or rendered directly) through drawn sensor noise, the deconvolver a study uses (the
design's own analytic kernel at s = 0, told the sensor's and the render's noise, as
:class:`~.rendered.CaptureScorer`) and :func:`~pacam_render.restore.object_score.score_capture`:
the moving objects', the still regions' and the whole window's PSNR, the fitted invariant
range (``record.design_fit``) and the light collected relative to a reference capture."""

from __future__ import annotations

import math

import numpy as np

from ..io.outputs import write_json, write_text
from ..restore.capture_score import deconvolve_capture, flat_sigma, radiance
from ..restore.object_score import moving_shapes, score_capture
from ..sensor.apply import apply_sensor, clean_level, sensor_sigma
from ..sensor.model import SensorModel
from .outputs import save_figure
from .rendered import DEFAULT_METHOD

SCORES = ("psnr_moving_db", "psnr_static_db", "psnr_db")
"""The three PSNRs (dB, white = 1): moving objects, still regions, whole window."""


def _mean_db(values) -> float | None:
    """The PSNR of the mean squared error of several PSNRs (dB); None where a draw has none
    (no still pixel in the scored columns gives inf, no moving object nan)."""
    if not all(math.isfinite(v) for v in values):
        return None
    return float(-10.0 * math.log10(np.mean([10.0 ** (-v / 10.0) for v in values])))


def _mean(values) -> float | None:
    got = [v for v in values if v is not None]
    return float(np.mean(got)) if got else None


def _db(v) -> str:
    return "n/a" if v is None else f"{v:.2f}"


def score_draws(cap, sensor: str, light_level, seeds, method: str = DEFAULT_METHOD) -> dict:
    """The three PSNRs of ``cap`` restored after each sensor draw in ``seeds``, their squared
    errors averaged over the draws (dB), and ``render_noise_ratio``: the capture's Monte Carlo
    sigma over the sensor's noise sigma, both as the deconvolver is told them. Designs compared
    at unequal ratios are compared in unequal noise."""
    model = SensorModel.from_preset(sensor)
    rec = cap.record
    render = flat_sigma(cap, rec.render_error.mc_sigma_white_units)
    sigma = flat_sigma(cap, sensor_sigma(rec, model, light_level, clean_level(cap)))
    per = {k: [] for k in SCORES}
    for seed in seeds:
        _, noisy, _ = apply_sensor(cap, model, light_level, seed)
        est = deconvolve_capture(cap, radiance(cap, noisy), math.hypot(sigma, render), method)
        s = score_capture(est, cap.extra_layers, rec)
        for k in SCORES:
            per[k].append(float(s[k]))
    ratio = render / sigma if sigma > 0 else float("nan")
    return {**{k: _mean_db(v) for k, v in per.items()}, "render_noise_ratio": float(ratio)}


def invariant_range(cap) -> float | None:
    """The smallest fitted invariant range over the moving objects (px/ms, at each one's
    depth; ``record.design_fit``), or None where the design has none (a bitmap, n/a)."""
    fit = cap.record.design_fit or {}
    moving = moving_shapes(cap.extra_layers, cap.record.objects or {})
    got = [e["range_px_per_ms"] for k, e in fit.items() if k in moving and "range_px_per_ms" in e]
    got = [g for g in got if g is not None and math.isfinite(g)]
    return min(got) if got else None


def design_row(design: str, where: str, cap, reference, sensor, light_level, seeds,
               method: str = DEFAULT_METHOD, unit: str | None = None) -> dict:  # fmt: skip
    """One report row: ``cap`` of ``design`` on ``where`` (a store or a fresh render), its
    three PSNRs, invariant range and light relative to ``reference``'s capture; ``unit``
    names the independent unit ``where`` belongs to (a scene, for one of its render seeds;
    :func:`paired` averages a unit's places), ``where`` itself if None."""
    return {
        "design": design,
        "where": where,
        "unit": where if unit is None else unit,
        **score_draws(cap, sensor, light_level, seeds, method),
        "range_px_per_ms": invariant_range(cap),
        "light_rel": float(cap.record.light_factor / reference.record.light_factor),
    }


def summary(rows: list[dict]) -> list[dict]:
    """Per design (in first-seen order) the mean over its rows of each score and its light."""
    out = []
    for name in dict.fromkeys(r["design"] for r in rows):
        mine = [r for r in rows if r["design"] == name]
        out.append({"design": name, "n": len(mine),
                    **{k: _mean([r[k] for r in mine]) for k in SCORES},
                    "range_px_per_ms": _mean([r["range_px_per_ms"] for r in mine]),
                    "render_noise_ratio": _mean([r.get("render_noise_ratio") for r in mine]),
                    "light_rel": float(np.mean([r["light_rel"] for r in mine]))})  # fmt: skip
    return out


def paired(rows: list[dict], score: str = "psnr_moving_db", ref: str = "prototype") -> dict:
    """Per design but ``ref``, its ``score`` minus ``ref``'s on the same capture place
    (``where``: a store, or a scene and render seed), paired: (mean, 95 % Student-t interval
    low, high, n); None where fewer than 2 units score both (a place with no still pixel in
    the scored columns has no still score).

    Places of one ``unit`` (a row's key, :func:`design_row`'s; its place where absent), such as
    two render seeds of one scene, are averaged first: their differences are not independent
    (a scene's two renders differ by its Monte Carlo noise, scenes by their content), so the
    interval is over units and n counts them.
    """
    from scipy.stats import t as student

    refs = {r["where"]: r[score] for r in rows if r["design"] == ref}
    out = {}
    for name in dict.fromkeys(r["design"] for r in rows if r["design"] != ref):
        units: dict = {}
        for r in rows:
            if r["design"] == name and r[score] is not None and refs.get(r["where"]) is not None:
                units.setdefault(r.get("unit", r["where"]), []).append(r[score] - refs[r["where"]])
        d = np.array([np.mean(v) for v in units.values()])
        if len(d) < 2:
            out[name] = None
            continue
        half = student.ppf(0.975, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
        out[name] = (float(d.mean()), float(d.mean() - half), float(d.mean() + half), len(d))
    return out


def markdown(rows: list[dict], title: str) -> str:
    """A table of :func:`summary`'s rows (n/a: a PSNR with no pixels, e.g. no still pixel
    inside the scored columns, or a design with no fitted range). Render noise: each capture's
    Monte Carlo sigma over the sensor's noise (:func:`score_draws`); designs at unequal ratios
    are compared in unequal noise."""
    lines = [f"## {title}", "",
             "| design | n | moving (dB) | still (dB) | whole (dB) | invariant range (px/ms) "
             "| light vs prototype | render noise / sensor |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in summary(rows):
        rng = "n/a" if r["range_px_per_ms"] is None else f"{r['range_px_per_ms']:.3f}"
        noise = r.get("render_noise_ratio")
        lines.append(f"| {r['design']} | {r['n']} | {_db(r['psnr_moving_db'])} | "
                     f"{_db(r['psnr_static_db'])} | {_db(r['psnr_db'])} | {rng} | "
                     f"{r['light_rel']:.2f}x | {'n/a' if noise is None else f'{noise:.2f}'} "
                     "|")  # fmt: skip
    return "\n".join(lines) + "\n"


def write_report(out, doc: dict, force: bool, text: str) -> list:
    """report.json (``doc``), report.md (``text``) and report.png (:func:`plot`)."""
    return [write_json(out / "report.json", doc, force=force),
            write_text(out / "report.md", text, force=force),
            save_figure(out / "report.png", lambda fig: plot(fig, doc), force)]  # fmt: skip


def write_patterns(path, code, title: str, force: bool):
    """patterns.png: each pattern window's code on the cells (transmittance, white open), in
    exposure order, the lens's rim drawn."""

    def draw(fig):
        from matplotlib.patches import Circle  # matplotlib loads only where a figure is drawn

        fig.set_size_inches(8, 8.4)
        n = len(code)
        cols = int(np.ceil(np.sqrt(n)))
        rows = int(np.ceil(n / cols))
        for k in range(n):
            ax = fig.add_subplot(rows, cols, k + 1)
            ax.imshow(code[k], cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            g = code.shape[-1]
            ax.add_patch(Circle(((g - 1) / 2, (g - 1) / 2), g / 2, fill=False, color="tab:red",
                                lw=0.6))  # fmt: skip
            ax.set_axis_off()
            ax.set_title(f"window {k}", fontsize=7)
        fig.suptitle(f"{title}: the LCoS patterns on {code.shape[-1]}x{code.shape[-1]} cells "
                     "(x right, y down; red: the clear aperture)", fontsize=9)  # fmt: skip

    return save_figure(path, draw, force)


def plot(fig, doc: dict) -> None:
    """The three PSNRs per design (bars, one panel per set of captures); the search curve."""
    sets = [k for k in ("train", "fresh", "held_out") if doc.get(k)]
    axes = [fig.add_subplot(1, len(sets) + 1, i + 1) for i in range(len(sets) + 1)]
    for ax, key in zip(axes, sets):
        rows = summary(doc[key])
        x = np.arange(len(rows))
        for j, (k, label) in enumerate(zip(SCORES, ("moving", "still", "whole"))):
            ax.bar(x + (j - 1) * 0.27, [np.nan if r[k] is None else r[k] for r in rows], 0.27,
                   label=label)  # fmt: skip
        ax.set_xticks(x, [r["design"] for r in rows], rotation=30, fontsize=7)
        ax.set(ylabel="PSNR (dB)", title=f"{key} captures")
        ax.legend(fontsize=7)
    curve = np.array(doc.get("curve") or [[0, 0, np.nan]], float)
    axes[-1].plot(curve[:, 0], curve[:, 2], lw=0.8)
    axes[-1].set(xlabel="iteration (all starts)", ylabel="model objective (dB)",
                 title="search (relaxed code)")  # fmt: skip
