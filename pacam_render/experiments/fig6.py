"""Fig. 6: PSNR against object speed, for several image accelerations a_i: flat inside the
motion-invariant range |s| <= a_i T, falling outside it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import simulate as E
from .figures import (
    MODELS,
    R_PX,
    SIGMA,
    T_MS,
    Figure,
    coded_kernel,
    mean_sem,
    pad_for,
    save_fig,
    sweep_scale,
)

FIG6_A = (0.008, 0.016, 0.032, 0.064, 0.128, 0.256)


def fig6(quick: bool, seed: int = 0) -> Figure:
    sc = sweep_scale(quick)
    imgs = E.load_images(sc["images"])
    speeds = np.geomspace(0.01, 4.0, sc["speeds"])
    rows = []
    for label, model in MODELS.items():
        for a in FIG6_A:
            k0 = coded_kernel(model, 0.0, a, R_PX)
            ks = [coded_kernel(model, s, a, R_PX) for s in speeds]
            scenes = E.Scenes(imgs, pad_for([k0, *ks]))
            for s, k in zip(speeds, ks):
                p = E.simulate(scenes, k, k0, E.gaussian_noise(SIGMA), seed, margin_px=16)
                m, se = mean_sem(p)
                rows.append(
                    {
                        "model": label,
                        "a_i_px_per_ms2": a,
                        "velocity_px_per_ms": float(s),
                        "psnr_db": m,
                        "psnr_sem_db": se,
                        "in_range": bool(s <= a * T_MS),
                    }
                )
    return Figure("fig6", rows, lambda path: _plot_fig6(rows, path), _summary_fig6(rows))


def _curves(rows, key_model, xkey, gkey):
    out = {}
    for r in rows:
        if r["model"] == key_model:
            out.setdefault(r[gkey], []).append((r[xkey], r["psnr_db"]))
    return {g: np.array(v) for g, v in out.items()}


def _plot_fig6(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, label in zip(axes, MODELS):
        for a, c in _curves(rows, label, "velocity_px_per_ms", "a_i_px_per_ms2").items():
            ax.semilogx(c[:, 0], c[:, 1], "o-", ms=3, label=f"a_i = {a:g}")
        ax.set_title(label)
        ax.set_xlabel("object speed s_i (px/ms)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("PSNR (dB)")
    axes[1].legend(fontsize=8)
    fig.suptitle("Fig. 6: PSNR vs object speed, deconvolved with the s = 0 PSF")
    save_fig(fig, path)


def flattening_db(curve: np.ndarray) -> float:
    """How far PSNR falls from its peak to the fastest speed, dB (small = flat)."""
    return float(curve[:, 1].max() - curve[-1, 1])


def _summary_fig6(rows) -> str:
    lines = [
        "| model | a_i | range (px/ms) | peak PSNR (dB) | PSNR at 4 px/ms | fall (dB) |",
        "|---|---|---|---|---|---|",
    ]
    stats = {}
    for label in MODELS:
        curves = _curves(rows, label, "velocity_px_per_ms", "a_i_px_per_ms2")
        stats[label] = [(c[:, 1].max(), flattening_db(c)) for c in curves.values()]
        for a, c in curves.items():
            lines.append(
                f"| {label} | {a:g} | {a * T_MS:.2f} | {c[:, 1].max():.2f} | "
                f"{c[-1, 1]:.2f} | {flattening_db(c):.2f} |"
            )
    label = next(iter(MODELS))
    peaks, falls = np.array(stats[label]).T
    agree = bool(np.all(np.diff(peaks) < 0) and falls[-1] < falls[0])
    return "\n".join(
        [
            "# Fig. 6: PSNR vs object speed",
            "",
            "**Paper:** PSNR is high for slow objects; a higher a_i flattens the curve over a wider "
            "range of speeds and lowers its peak.",
            "",
            f"**Ours ({label}):** the peak falls from {peaks[0]:.1f} dB (a_i = {FIG6_A[0]:g}) to "
            f"{peaks[-1]:.1f} dB (a_i = {FIG6_A[-1]:g}), and the fall from the peak to 4 px/ms "
            f"shrinks from {falls[0]:.1f} to {falls[-1]:.1f} dB. **{'Agrees' if agree else 'Differs'}.**",
            "",
            "**Where the camera differs from the model:** the 16 held patterns jump by up to "
            "a_i T (2T/16) px between patterns (8 px at a_i = 0.128), so at high a_i the PSF is 16 "
            "separate discs whose spectrum has near-zeros that move with speed: PSNR dips by "
            "several dB at some speeds inside the range, which Eq. 14 does not predict.",
            "",
            "Set-up: r = 2 px, 2T = 45 ms, Gaussian sigma = 0.01, Wiener with the 1/f^2 prior; each "
            "estimate is aligned (sub-pixel) before PSNR because the invariant PSF shifts the image "
            "by -s^2/(2 a_i). Mean over the images (standard error in the CSV).",
            "",
            *lines,
        ]
    )
