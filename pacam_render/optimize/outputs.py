"""What ``pacam optimize`` writes: schedule.json, the LCoS bitmaps, plots and report.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outputs import atomic_save, write_json, write_text
from ..io.preview import write_png
from ..model.camera import CameraDesign
from ..model.modes import local_centres_mm
from ..model.schedule_fit import schedule_figures
from ..psf.analytic import design_psf
from ..render.masks import disc_mask
from .objective import SOFTMAX_DB, Objective


def designed_camera(obj: Objective, theta) -> CameraDesign:
    """The reference design showing the optimised schedule (centres, focus, radius)."""
    X, beta0, R = obj.unpack(theta)
    return obj.ref.with_(
        R_mm=R,
        focus_distance_mm=obj.focus_mm(beta0),
        pattern_centres_mm=tuple((float(x), 0.0) for x in X),
        name="optimised schedule",
        quoted_a_i_px_per_ms2=None,
    )


FIGURES = (
    "a_i_fitted_px_per_ms2",
    "velocity_range_fitted_px_per_ms",
    "velocity_centre_fitted_px_per_ms",
    "fit_rms_residual_px",
    "fit_method",
    "fit_undefined_reason",
    "open_fraction",
)
"""The keys of :func:`~pacam_render.model.schedule_fit.schedule_figures` that schedule.json
records for the optimised schedule: its a_i and invariant range fitted to its own image
trajectory (Eq. 18 describes only the parabola)."""


def _parabola_figures(parabola: dict) -> dict:
    """The parabola's Eq. 18 range and its fitted a_i (equal to Eq. 18's to rounding)."""
    cam = parabola["camera"]
    return {
        "parabola_velocity_range_px_per_ms": cam.velocity_range_px_per_ms,
        "parabola_a_i_fitted_px_per_ms2": schedule_figures(cam)["a_i_fitted_px_per_ms2"],
    }


def schedule_document(problem, obj: Objective, best, parabola: dict, run: dict) -> dict:
    """The schedule.json object (keys: :mod:`pacam_render.model.schedule_file`), with the
    schedule's fitted figures (:data:`FIGURES`) and the parabola's for comparison."""
    cam = designed_camera(obj, best.theta)
    p = obj.psnr_db(best.theta)
    fig = schedule_figures(cam)
    return {
        "centres_mm": [list(c) for c in cam.pattern_centres_mm],
        "radius_mm": cam.R_mm,
        "focus_distance_mm": cam.focus_distance_mm,
        "n_patterns": cam.n_patterns,
        "exposure_ms": cam.exposure_ms,
        "object_depth_mm": cam.object_depth_mm,
        "objective": "predicted PSNR (dB, white = 1) of Wiener deblurring with the s = 0 kernel "
        "at the design depth, 1/f^2 prior, each speed at its best shift; higher is better",
        "objective_worst": float(p.min()),
        "objective_mean": float(p.mean()),
        "parabola_objective_worst": parabola["worst"],
        "parabola_objective_mean": parabola["mean"],
        "parabola": parabola["design"],
        "max_velocity_px_per_ms": problem.max_velocity_px_per_ms,
        "depth_range_mm": list(problem.depth_range_mm),
        "sensor": problem.sensor,
        "light_level_photons_per_px_per_ms": problem.light_level,
        "noise_sigma_white_units": float(np.sqrt(obj.noise_var(cam.R_mm))),
        "preset": problem.preset,
        "width_px": cam.width_px,
        "r_px": cam.r_px,
        "beta_px_per_mm": cam.beta_px_per_mm,
        "speeds_px_per_ms": obj.grid.speeds.tolist(),
        "depths_mm": obj.grid.depths_mm.tolist(),
        "predicted_psnr_db": p.tolist(),
        "parabola_predicted_psnr_db": parabola["psnr"].tolist(),
        **{k: fig[k] for k in FIGURES},
        **_parabola_figures(parabola),
        **run,
    }


def write_bitmaps(out: Path, cam: CameraDesign, force: bool) -> list[Path]:
    """The n LCoS patterns, 1280x1024 8-bit PNG: an opening's pixels white (binary, pixel
    centres inside the disc), in the image's orientation (x right, y down)."""
    paths = []
    for k, c in enumerate(local_centres_mm(cam)):
        m = disc_mask(c, cam.R_mm, pitch_mm=cam.lcos_pitch_mm)
        paths.append(write_png(out / "lcos" / f"pattern_{k:02d}.png", (m * 255).astype(np.uint8),
                               force=force))  # fmt: skip
    return paths


def plot_all(out: Path, obj: Objective, best, parabola: dict, starts, force: bool) -> list[Path]:
    """schedule.png, psnr.png, psf.png and convergence.png."""
    th = best.theta
    return [
        save_figure(
            out / "schedule.png", lambda fig: _plot_schedule(fig, obj, th, parabola), force
        ),
        save_figure(out / "psnr.png", lambda fig: _plot_psnr(fig, obj, th, parabola), force),
        save_figure(out / "psf.png", lambda fig: _plot_psfs(fig, obj, th, parabola), force),
        save_figure(out / "convergence.png", lambda fig: _plot_convergence(fig, starts), force),
    ]


def save_figure(path: Path, draw, force: bool) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10, 4))
    draw(fig)
    fig.tight_layout()
    atomic_save(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"), force)
    plt.close(fig)
    return path


def _plot_schedule(fig, obj: Objective, theta, parabola: dict) -> None:
    X, _, R = obj.unpack(theta)
    t = obj.t_k
    ax = fig.add_subplot(1, 2, 1)
    a_eq18 = parabola["camera"].a_i_px_per_ms2
    ax.step(t, parabola["theta_X"], "o-", where="mid",
            label=f"parabola (paper, Eq. 18 a_i {a_eq18:.3g} px/ms$^2$)")  # fmt: skip
    a_fit = schedule_figures(designed_camera(obj, theta))["a_i_fitted_px_per_ms2"]
    fitted = "undefined" if a_fit is None else f"{a_fit:.3g} px/ms$^2$"
    ax.step(t, X, "s-", where="mid", label=f"optimised (fitted a_i {fitted})")
    ax.axhline(obj.R_max - R, color="k", lw=0.5)
    ax.axhline(-(obj.R_max - R), color="k", lw=0.5)
    ax.set(
        xlabel="t (ms)", ylabel="opening centre x (mm)", title=f"the {len(X)} openings over time"
    )
    ax.legend(fontsize=8)
    ax = fig.add_subplot(1, 2, 2, aspect="equal")
    import matplotlib.pyplot as plt

    ax.add_patch(plt.Circle((0, 0), obj.R_max, fill=False))
    for k, x in enumerate(X):
        ax.add_patch(plt.Circle((x, 0), R, alpha=0.15, color=plt.cm.viridis(k / len(X))))
    ax.set(xlim=(-obj.R_max, obj.R_max), ylim=(-obj.R_max, obj.R_max), xlabel="x (mm)",
           ylabel="y (mm)", title="openings on the lens (colour: time)")  # fmt: skip


def _plot_psnr(fig, obj: Objective, theta, parabola: dict) -> None:
    ax = fig.add_subplot(1, 1, 1)
    p = obj.psnr_db(theta)
    for z, depth in enumerate(obj.grid.depths_mm):
        ax.plot(obj.grid.speeds, parabola["psnr"][z], "--", label=f"parabola, {depth:.0f} mm")
        ax.plot(obj.grid.speeds, p[z], "-", label=f"optimised, {depth:.0f} mm")
    ax.set(xlabel="object speed s (px/ms)", ylabel="predicted PSNR (dB)",
           title="predicted PSNR against speed, one kernel (s = 0) for all")  # fmt: skip
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def _plot_psfs(fig, obj: Objective, theta, parabola: dict) -> None:
    """Each schedule's PSF at three speeds (px, one colour scale per row) and its OTF by speed."""

    fig.set_size_inches(12, 5)
    cam = designed_camera(obj, theta)
    s_max = obj.grid.speeds[-1]
    speeds = (0.0, 0.5 * s_max, s_max)
    for row, (label, design) in enumerate((("parabola", parabola["camera"]), ("optimised", cam))):
        kernels = [design_psf(design, "coded", s, origin="pinhole") for s in speeds]
        vmax = max(float(k.max()) for k in kernels)
        for j, (s, k) in enumerate(zip(speeds, kernels)):
            ax = fig.add_subplot(2, 4, 4 * row + j + 1)
            im = _show_psf(ax, k, vmax)
            ax.set_title(f"{label}, s = {s:.2g} px/ms", fontsize=8)
            ax.set_xlabel("x (px)", fontsize=7)
            if j == 0:
                ax.set_ylabel("y (px)", fontsize=7)
        fig.colorbar(im, ax=ax, label="light per px (fraction)", shrink=0.8)
        ax = fig.add_subplot(2, 4, 4 * row + 4)
        _, _, f = obj.errors(theta if label == "optimised" else parabola["theta"])
        mag = np.abs(f["H"][obj.grid.z0, :, :, 0])
        im = ax.imshow(np.log10(mag + 1e-4), aspect="auto", cmap="viridis", origin="lower",
                       extent=(0, 0.5, obj.grid.speeds[0], s_max))  # fmt: skip
        ax.set_title(f"{label}: |OTF(f_x)| by speed", fontsize=8)
        ax.set_xlabel("f_x (cycles/px)", fontsize=7)
        ax.set_ylabel("s (px/ms)", fontsize=7)
        fig.colorbar(im, ax=ax, label="log10 |OTF|", shrink=0.8)


def _show_psf(ax, k: np.ndarray, vmax: float):
    """A kernel's central rows (up to 25) in px from its centre pixel, on a shared scale."""
    h, w = k.shape
    c = h // 2
    lo, hi = max(0, c - 12), min(h, c + 13)
    extent = (-(w // 2) - 0.5, w - w // 2 - 0.5, hi - c - 0.5, lo - c - 0.5)
    return ax.imshow(k[lo:hi], cmap="magma", aspect="auto", vmin=0.0, vmax=vmax, extent=extent)


def _plot_convergence(fig, starts) -> None:
    ax = fig.add_subplot(1, 2, 1)
    ax2 = fig.add_subplot(1, 2, 2)
    for s in starts:
        it = np.array(s.iterations)
        ax.plot(it[:, 0], -it[:, 2], label=f"start {s.index}")
        ax2.plot(it[:, 1], -it[:, 2])
    ax.set(xlabel="iteration", ylabel="soft worst-case PSNR (dB)", title="objective per start")
    ax2.set(xlabel="seconds since the first start", ylabel="soft worst-case PSNR (dB)")
    ax.legend(fontsize=7)
    for a in (ax, ax2):
        a.grid(alpha=0.3)


def write_report(out: Path, doc: dict, starts, force: bool) -> Path:
    """report.md: the result, the parabola at equal light, and the optimiser's runs."""
    gain_w = doc["objective_worst"] - doc["parabola_objective_worst"]
    gain_m = doc["objective_mean"] - doc["parabola_objective_mean"]
    rows = [
        f"| {s.index} | {len(s.iterations) - 1} | {s.iterations[-1][1]:.1f} | "
        f"{s.worst_db:.2f} | {s.mean_db:.2f} |"
        for s in starts
    ]
    lines = [
        "# Optimised aperture schedule",
        "",
        f"Speeds |s| <= {doc['max_velocity_px_per_ms']:g} px/ms, depths "
        f"{doc['depth_range_mm'][0]:g}-{doc['depth_range_mm'][1]:g} mm, {doc['n_patterns']} "
        f"patterns in {doc['exposure_ms']:g} ms, sensor `{doc['sensor']}` (noise sigma "
        f"{doc['noise_sigma_white_units']:.4f} of white), {doc['width_px']} px wide.",
        "",
        "| schedule | worst PSNR (dB) | mean PSNR (dB) | radius (mm) | focus (mm) | r (px) |",
        "|---|---|---|---|---|---|",
        f"| parabola (paper) | {doc['parabola_objective_worst']:.2f} | "
        f"{doc['parabola_objective_mean']:.2f} | {doc['parabola']['R_mm']:.4f} | "
        f"{doc['parabola']['focus_distance_mm']:.1f} | {doc['parabola']['r_px']:.2f} |",
        f"| optimised | {doc['objective_worst']:.2f} | {doc['objective_mean']:.2f} | "
        f"{doc['radius_mm']:.4f} | {doc['focus_distance_mm']:.1f} | {doc['r_px']:.2f} |",
        "",
        f"Gain at equal light: **{gain_w:+.2f} dB** worst case, {gain_m:+.2f} dB mean "
        "(predicted: " + doc["objective"] + ").",
        "",
        *_motion_table(doc),
        *_reading_notes(doc, starts),
        "## The optimiser",
        "",
        f"{len(starts)} L-BFGS-B starts from seed {doc['seed']} (start 0: the parabola), "
        f"{doc['seconds']:.1f} s in all.",
        "",
        "| start | iterations | seconds at its end | worst (dB) | mean (dB) |",
        "|---|---|---|---|---|",
        *rows,
        "",
        "Plots: `schedule.png`, `psnr.png`, `psf.png`, `convergence.png`. LCoS bitmaps: "
        "`lcos/pattern_NN.png`. Render with `pacam render SCENE --schedule schedule.json`.",
    ]
    return write_text(out / "report.md", "\n".join(lines) + "\n", force)


def _num(v, fmt: str) -> str:
    return "undefined" if v is None else format(v, fmt)


def _motion_table(doc: dict) -> list[str]:
    """a_i and the invariant range of both schedules: Eq. 18 for the parabola, fitted to the
    optimised schedule's image trajectory (its own held patterns) for the optimised one."""
    n = doc["n_patterns"]
    a_fit = doc["a_i_fitted_px_per_ms2"]
    centre = doc["velocity_centre_fitted_px_per_ms"]
    half = doc["velocity_range_fitted_px_per_ms"] or 0.0
    off_centre = centre is not None and abs(centre) > 1e-3 * max(half, 1e-6)  # > 0.1 %
    lines = [
        "| schedule | a_i (px/ms^2) | invariant range (px/ms) | from |",
        "|---|---|---|---|",
        f"| parabola (paper) | {doc['parabola']['a_i_px_per_ms2']:.4g} | "
        f"{doc['parabola_velocity_range_px_per_ms']:.4g} | Eq. 18 (fitted to its {n} patterns: "
        f"{_num(doc['parabola_a_i_fitted_px_per_ms2'], '.4g')}) |",
        f"| optimised | {_num(a_fit, '.4g')} | "
        f"{_num(doc['velocity_range_fitted_px_per_ms'], '.4g')}"
        + (f", centred on s = {centre:.3g}" if off_centre else "")
        + f" | fitted to the schedule's image trajectory ({n} patterns"
        + (
            ""
            if doc["fit_rms_residual_px"] is None
            else f", RMS residual {doc['fit_rms_residual_px']:.3g} px"
        )
        + ") |",
        "",
        f"Open fraction {doc['open_fraction']:.4f} of the full lens for both (equal light). The "
        "optimised schedule's a_i comes from a least-squares parabola whose window means match "
        "its held image offsets (`fit_method` in schedule.json); Eq. 18 holds only for the "
        "parabola.",
    ]
    if doc["fit_undefined_reason"]:
        lines.append(f"No fitted a_i: {doc['fit_undefined_reason']}.")
    return [*lines, ""]


FAR_FOCUS = 100.0
"""A focus beyond this many object depths is reported as at infinity (the search's bound on
that side is 1000 object depths: beta_0 at 0.999 of f_px / Z_0)."""


def _worst_at(doc: dict, key: str) -> str:
    """Where the grid's lowest predicted PSNR lies: its speed and depth."""
    p = np.asarray(doc[key])
    z, s = np.unravel_index(np.argmin(p), p.shape)
    return f"s = {doc['speeds_px_per_ms'][s]:.2f} px/ms, {doc['depths_mm'][z]:g} mm"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _reading_notes(doc: dict, starts) -> list[str]:
    """What the two worst-case figures are, and what a focus at infinity means."""
    n_grid = len(doc["speeds_px_per_ms"]) * len(doc["depths_mm"])
    best = next(s for s in starts if s.index == doc["best_start"])
    soft = -best.iterations[-1][2]
    grid = f"{len(doc['speeds_px_per_ms'])} speeds x {_count(len(doc['depths_mm']), 'depth')}"
    mine = _worst_at(doc, "predicted_psnr_db")
    theirs = _worst_at(doc, "parabola_predicted_psnr_db")
    lines = [
        "## Reading it",
        "",
        f"- **Worst PSNR** is the lowest predicted PSNR over the grid of {grid} (`psnr.png`): "
        f"the optimised schedule's at {mine}, the parabola's at {theirs}. The best start is "
        "chosen by it, and the gain above is the difference of the two schedules' worst PSNR at "
        "the same opening (equal light, equal noise).",
        f"- **Soft worst case** (`convergence.png`) is what L-BFGS-B maximises: a smooth minimum "
        f"of the same grid (log-sum-exp at {SOFTMAX_DB:g} dB), so that the search has a gradient"
        f". It is at least the worst PSNR and at most {SOFTMAX_DB * np.log(n_grid):.2f} dB above"
        f" it ({SOFTMAX_DB:g} ln {n_grid}), as near speeds count too: {soft:.2f} dB at the best "
        f"start's end against its worst PSNR of {best.worst_db:.2f} dB.",
    ]
    if doc["focus_distance_mm"] >= FAR_FOCUS * doc["object_depth_mm"]:
        lines.append(_far_focus_note(doc))
    return [*lines, ""]


def _far_focus_note(doc: dict) -> str:
    beta = abs(doc["beta_px_per_mm"])
    z0 = doc["object_depth_mm"]
    return (
        f"- **Focus at infinity.** {doc['focus_distance_mm']:.0f} mm is the search's bound: "
        "the lens focused at infinity. The focus sets beta_0, the image shift per mm the "
        "opening travels (Eq. 9), at the design depth: with the focus behind the object, "
        "|beta_0| = f_px (1/Z_0 - 1/Z_f) grows as the focus recedes, to f_px / Z_0 at infinity "
        f"({beta:.2f} px/mm here). More shift per mm spans more image motion with the same "
        "travel, and the optimiser took all it could; the price is defocus, r = |beta_0| R = "
        f"{doc['r_px']:.2f} px at {z0:g} mm (the parabola's r is "
        f"{doc['parabola']['r_px']:.2f} px). Nothing is then in focus: the defocus radius falls "
        f"as 1/Z behind {z0:g} mm (half of it at {2 * z0:g} mm) and grows in front of it."
    )


def write_schedule_json(out: Path, doc: dict, force: bool) -> Path:
    return write_json(out / "schedule.json", doc, force)
