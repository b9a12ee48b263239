"""What ``pacam optimize`` writes: schedule.json, the LCoS bitmaps, plots and report.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outputs import atomic_save, write_json, write_text
from ..io.preview import write_png
from ..model.camera import CameraDesign
from ..model.modes import local_centres_mm
from ..render.masks import disc_mask
from .objective import Objective


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


def schedule_document(problem, obj: Objective, best, parabola: dict, run: dict) -> dict:
    """The schedule.json object (keys: :mod:`pacam_render.model.schedule_file`)."""
    cam = designed_camera(obj, best.theta)
    p = obj.psnr_db(best.theta)
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
        _save(out / "schedule.png", lambda fig: _plot_schedule(fig, obj, th, parabola), force),
        _save(out / "psnr.png", lambda fig: _plot_psnr(fig, obj, th, parabola), force),
        _save(out / "psf.png", lambda fig: _plot_psfs(fig, obj, th, parabola), force),
        _save(out / "convergence.png", lambda fig: _plot_convergence(fig, starts), force),
    ]


def _save(path: Path, draw, force: bool) -> Path:
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
    ax.step(t, parabola["theta_X"], "o-", where="mid", label="parabola (paper)")
    ax.step(t, X, "s-", where="mid", label="optimised")
    ax.axhline(obj.R_max - R, color="k", lw=0.5)
    ax.axhline(-(obj.R_max - R), color="k", lw=0.5)
    ax.set(xlabel="t (ms)", ylabel="opening centre x (mm)", title="the 16 openings over time")
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
    from ..psf.analytic import design_psf

    cam = designed_camera(obj, theta)
    s_max = obj.grid.speeds[-1]
    speeds = (0.0, 0.5 * s_max, s_max)
    for row, (label, design) in enumerate((("parabola", parabola["camera"]), ("optimised", cam))):
        for j, s in enumerate(speeds):
            k = design_psf(design, "coded", s, origin="pinhole")
            ax = fig.add_subplot(2, 4, 4 * row + j + 1)
            c = k.shape[0] // 2
            ax.imshow(k[max(0, c - 12) : c + 13], cmap="magma", aspect="auto")
            ax.set_title(f"{label}, s = {s:.2g}", fontsize=8)
            ax.set_axis_off()
        ax = fig.add_subplot(2, 4, 4 * row + 4)
        _, _, f = obj.errors(theta if label == "optimised" else parabola["theta"])
        mag = np.abs(f["H"][obj.grid.z0, :, :, 0])
        ax.imshow(np.log10(mag + 1e-4), aspect="auto", cmap="viridis", origin="lower",
                  extent=(0, 0.5, obj.grid.speeds[0], s_max))  # fmt: skip
        ax.set_title(f"{label}: log10 |OTF(f_x)| by speed", fontsize=8)
        ax.set_xlabel("f_x (cycles/px)", fontsize=7)


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


def write_schedule_json(out: Path, doc: dict, force: bool) -> Path:
    return write_json(out / "schedule.json", doc, force)
