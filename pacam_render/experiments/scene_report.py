"""The files of ``pacam validate-scene``: the error map, the table, the layers and the summary.

``validate_scene.png``: the capture, the model, the regions and the error in noise units;
``validate_scene.csv``: one row per model and region; ``validate_scene.exr``: the layers
(the mean capture, both models, the error maps, the regions and the truth);
``validate_scene.md``: the findings; ``validate_scene.json``: every number and setting.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..io.exr import write_exr
from ..io.outputs import csv_text, save_figure, write_json, write_text
from ..model.camera import preset
from ..model.design_file import resolve_design
from ..scenes import load_scene
from ..scenes.edit import scene_speed_px_per_ms
from .scene_error import PROFILE_RATIO, residuals
from .scene_regions import REGIONS

Z_SPAN = 5.0
"""The error maps show -5 to 5 noise sigmas."""
NOISE_WINDOW_PX = 15
"""Side of the box over which the error map's local noise is estimated, px."""
REGION_COLOURS = ("#000000", "#9ecae1", "#3182bd", "#fdae6b", "#e6550d", "#a1d99b")


def write(out: Path, summary: dict, r, predicted: dict, reg: np.ndarray, force: bool) -> list:
    """Write every file into ``out``; returns their names."""
    z = {name: z_map(r.captures, predicted[name]) for name in predicted}
    files = ["validate_scene.csv", "validate_scene.json", "validate_scene.md"]
    write_text(out / files[0], csv_text(summary["rows"], "{:.6g}"), force=force)
    write_json(out / files[1], _finite({k: v for k, v in summary.items() if k != "files"}), force)
    files += [
        _layers(out, r, predicted, z, reg, summary, force),
        _figure(out, r, predicted, z, reg, summary),
    ]
    write_text(out / files[2], markdown(summary, files), force=force)
    return files


def _finite(obj):
    """JSON has no infinity: an infinite ceiling (no excess error) is written as null."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    return None if isinstance(obj, float) and math.isinf(obj) else obj


def z_map(captures, predicted) -> np.ndarray:
    """The error of the mean, in local noise sigmas (grey: the mean over channels)."""
    from scipy.ndimage import uniform_filter

    e, d = (x.mean(-1) for x in residuals(captures, predicted))
    local = uniform_filter(d * d / 4.0, NOISE_WINDOW_PX, mode="reflect")
    noise = np.sqrt(np.maximum(local, 0.0))  # the running sums round to -1e-20 in flat areas
    return e / np.maximum(noise, 1e-12)


def _layers(out: Path, r, predicted: dict, z: dict, reg, summary: dict, force: bool) -> str:

    x, y, w, h = _inner_box(summary)
    truth = {k: v[y : y + h, x : x + w] for k, v in r.truths[0].items()}
    layers = {"capture": 0.5 * (r.captures[0] + r.captures[1])}
    layers.update({f"model_{k}": 0.5 * (v[0] + v[1]) for k, v in predicted.items()})
    layers.update({f"z_{k}": v for k, v in z.items()})
    layers["region"] = reg.astype(np.float32)
    layers.update(truth)
    write_exr(out / "validate_scene.exr", layers, force=force)
    return "validate_scene.exr"


def _inner_box(summary: dict) -> tuple[int, int, int, int]:
    """The capture's window inside the truth window (x, y, w, h)."""
    s = summary["settings"]
    (cx, cy, w, h), (tx, ty, _, _) = s["crop"], s["truth_crop"]
    return cx - tx, cy - ty, w, h


def _figure(out: Path, r, predicted: dict, z: dict, reg, summary: dict) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    cap = 0.5 * (r.captures[0] + r.captures[1])
    model = 0.5 * (predicted["composite"][0] + predicted["composite"][1])
    h, w = reg.shape
    fig, axes = plt.subplots(2, 3, figsize=(12, min(8 * h / w, 12) + 1.5))
    gain = 1.0 / max(float(np.percentile(cap, 99.5)), 1e-6)  # dark scenes shown exposed
    panels = [
        (axes[0, 0], np.clip(gain * cap, 0, 1), f"capture (two seeds' mean) x {gain:.3g}", {}),
        (axes[0, 1], np.clip(gain * model, 0, 1), "convolution model (composite)", {}),
        (axes[1, 0], z["composite"], "error, composite (noise sigmas)", _z_style()),
        (axes[1, 1], z["layered"], "error, layered (noise sigmas)", _z_style()),
    ]
    for ax, img, title, style in panels:
        im = ax.imshow(img, interpolation="nearest", **style)
        ax.set_title(title, fontsize=9)
        if style:
            fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="error / local noise sigma")
    cmap = ListedColormap(REGION_COLOURS)
    axes[0, 2].imshow(reg, cmap=cmap, vmin=-0.5, vmax=len(REGIONS) - 0.5, interpolation="nearest")
    axes[0, 2].set_title("regions", fontsize=9)
    _region_legend(axes[0, 2], cmap)
    for ax in axes.ravel()[:5]:
        ax.set_xticks([])
        ax.set_yticks([])
    _profile_plot(axes[1, 2], summary)
    fig.tight_layout()
    save_figure(fig, out / "validate_scene.png", 90)
    return "validate_scene.png"


def _z_style() -> dict:
    return {"cmap": "RdBu_r", "vmin": -Z_SPAN, "vmax": Z_SPAN}


def _region_legend(ax, cmap) -> None:
    from matplotlib.patches import Patch

    handles = [Patch(color=cmap(k), label=name.replace("_", " ")) for k, name in enumerate(REGIONS)]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=2, fontsize=7)


def _profile_plot(ax, summary: dict) -> None:
    """Error in noise sigmas against signed distance to a moving edge, both models."""
    for model in ("composite", "layered"):
        rows = [r for r in summary["profile"] if r["model"] == model]
        ax.plot([r["distance_px"] for r in rows], [r["ratio"] for r in rows], ".-", label=model)
    reach = summary["reach_px"]["moving"]
    for x in (-reach, reach):
        ax.axvline(x, color="grey", lw=0.8, ls=":")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("distance to a moving edge, px (< 0: on the moving object)", fontsize=8)
    ax.set_ylabel("rms error / rms noise", fontsize=8)
    ax.set_title("error against distance (dotted: the PSF reach)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.3g}"
    return str(v)


def _table(rows: list[dict], keys: tuple[str, ...]) -> list[str]:
    out = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    out += ["| " + " | ".join(_fmt(row.get(k, "")) for k in keys) + " |" for row in rows]
    return out


ROW_KEYS = (
    "region", "pixels", "noise_rms", "error_rms", "ratio", "model_rms", "psnr_ceiling_db",
    "bias", "at_floor",
)  # fmt: skip


PROFILE_KEYS = ("model", "distance_px", "pixels", "ratio", "model_rms", "psnr_ceiling_db", "bias")


def _optics_line(optics: dict | None) -> list[str]:
    """What the comparison did with the capture's relative illumination and diffraction."""
    if not optics:
        return []
    flat = f"relative illumination {optics['relative_illumination']}"
    if optics["flat_fielded"]:
        flat += ", flat-fielded before the comparison"
    diff = f"diffraction {optics['diffraction']}"
    if optics["model_diffracted"]:
        diff += "; the model is convolved with the same Fraunhofer kernels"
    return [f"Optics: {flat}; {diff}.", ""]


def markdown(summary: dict, files: list[str]) -> str:
    """The report: settings, findings, the tables by model, and the quantum sweep."""
    s, cam = summary["settings"], summary["camera"]
    x, y, w, h = s["crop"]
    lines = [
        f"# validate-scene: {s['scene']} ({s['mode']})",
        "",
        f"A {w}x{h} px window at ({x}, {y}) of the {cam['width_px']}x{cam['height_px']} px "
        f"sensor, {s['spp']} spp, seeds {s['seeds'][0]} and {s['seeds'][1]}; truth rendered "
        f"{s['margin_px']} px wider on each side. Camera at this scale: r = "
        f"{cam['r_px']:.3g} px, a_i = {cam['a_i_px_per_ms2']:.3g} px/ms^2 at its design depth "
        f"{cam['object_depth_mm']:.4g} mm (invariant |s| <= "
        f"{cam['velocity_range_px_per_ms']:.3g} px/ms). The model has {summary['cells']} "
        f"cells (quantum {s['quantum_px']} px); PSFs reach {summary['reach_px']['moving']:.1f} "
        f"px (moving) and {summary['reach_px']['still']:.1f} px (still): the band widths.",
        "",
        *_optics_line(summary.get("optics")),
        f"Rendering took {summary['render_s']:.1f} s, the model {summary['model_s']:.1f} s per "
        f"seed. Files: {', '.join(files)}.",
        "",
        "## Findings",
        "",
        *findings(summary["rows"], summary["profile_width_px"]),
    ]
    for model in ("composite", "layered"):
        rows = [r for r in summary["rows"] if r["model"] == model]
        lines += ["", f"## {model}", "", *_table(rows, ROW_KEYS)]
    lines += ["", "## Error against distance to a moving edge (< 0: on the moving object)", ""]
    lines += _table(summary["profile"], PROFILE_KEYS)
    lines += ["", "## The model's discretisation: error against run time", ""]
    keys = tuple(summary["sweep"][0])
    lines += _table(summary["sweep"], keys)
    lines += ["", _COLUMNS_NOTE]
    return "\n".join(lines) + "\n"


_COLUMNS_NOTE = (
    "ratio: rms error of the two seeds' mean over rms of the noise that their difference "
    "measures (1 = at the Monte Carlo floor); model_rms: the error with that noise taken out, "
    "white = 1; psnr_ceiling_db: -10 log10(model_rms^2), the PSNR of the model against a "
    "noiseless capture in that region; bias: the mean error (capture - model); at_floor: ratio^2 "
    "- 1 within 3 standard errors of 0."
)


def findings(rows: list[dict], widths: dict | None = None) -> list[str]:
    """One sentence per region (the composite model's rows), and the edge profile's width."""
    by = {r["region"]: r for r in rows if r["model"] == "composite"}
    out = []
    for name in REGIONS[1:]:
        if name not in by:
            continue
        r = by[name]
        floor = "at the noise floor" if r["at_floor"] else "statistically above it"
        out.append(
            f"- {name.replace('_', ' ')} ({r['pixels']} px): error/noise = {r['ratio']:.3g} "
            f"({floor}); model RMS {r['model_rms']:.2g}, PSNR ceiling "
            f"{_fmt(r['psnr_ceiling_db'])} dB."
        )
    for model, (inside, outside) in (widths or {}).items():
        out.append(
            f"- {model}: the error is above the noise (ratio > {PROFILE_RATIO:g}, beyond 3 "
            f"standard errors) up to {inside:g} px inside and {outside:g} px outside a moving edge."
        )
    return out or ["- no scored pixels (every pixel is in the frame band)"]


COLLECT_KEYS = (
    "run", "scene", "speed_px_per_ms", "r_px", "window", "cells", "model",
    "moving_interior", "still_interior", "moving_edge_band", "background_near_moving",
    "band_psnr_ceiling_db", "edge_px_inside", "edge_px_outside",
)  # fmt: skip


def collect(folder) -> str:
    """A table of every ``validate_scene.json`` under ``folder`` (one row per run and model):
    the error/noise by region, the PSNR ceiling of the occlusion band (its two regions pooled)
    and the edge profile's width. Written to ``folder/summary.md``."""
    rows = []
    for path in sorted(Path(folder).glob("*/validate_scene.json")):
        summary = json.loads(path.read_text())
        rows += [_collect_row(path.parent.name, summary, m) for m in ("composite", "layered")]
    if not rows:
        raise ParameterError(f"no validate_scene.json under {folder}")
    lines = ["| " + " | ".join(COLLECT_KEYS) + " |", "|" + "---|" * len(COLLECT_KEYS)]
    lines += ["| " + " | ".join(_fmt(r.get(k, "")) for k in COLLECT_KEYS) + " |" for r in rows]
    text = "\n".join(lines) + "\n"
    write_text(Path(folder) / "summary.md", text, force=True)
    return text


def _default_speed(settings: dict) -> float:
    """The scene's own fastest speed at the capture's resolution (for reports written before
    the summary recorded it)."""

    if settings.get("speed_px_per_ms"):
        return settings["speed_px_per_ms"]
    if settings.get("design"):
        return scene_speed_px_per_ms(
            load_scene(settings["scene"]), resolve_design(settings["design"])
        )
    return scene_speed_px_per_ms(load_scene(settings["scene"]), preset(settings["preset"]))


def _collect_row(name: str, s: dict, model: str) -> dict:
    by = {r["region"]: r for r in s["rows"] if r["model"] == model}
    band = [by[k] for k in ("moving_edge_band", "background_near_moving") if k in by]
    pixels = sum(r["pixels"] for r in band)
    mse = sum(r["pixels"] * r["model_rms"] ** 2 for r in band) / max(pixels, 1)
    x, y, w, h = s["settings"]["crop"]
    inside, outside = s["profile_width_px"][model]
    row = {
        "run": name,
        "scene": s["settings"]["scene"],
        "speed_px_per_ms": s.get("speed_px_per_ms") or _default_speed(s["settings"]),
        "r_px": s["camera"]["r_px"],
        "window": f"{w}x{h}",
        "cells": s["cells"],
        "model": model,
        "band_psnr_ceiling_db": -10 * math.log10(mse) if mse > 0 else math.inf,
        "edge_px_inside": inside,
        "edge_px_outside": outside,
    }
    row.update({k: by[k]["ratio"] for k in COLLECT_KEYS if k in by})
    return row
