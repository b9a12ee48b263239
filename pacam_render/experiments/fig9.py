"""Fig. 9: PSNR against object depth for a deconvolver that assumes one depth: the range of
depths that a single assumed kernel tolerates."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.camera import prototype
from ..psf import analytic as P
from . import simulate as E
from .figures import SIGMA, Figure, mean_sem, pad_for, save_fig, sweep_scale

FIG9_ASSUMED_MM = (300.0, 500.0, 1000.0, 2000.0, 3000.0)


def fig9(quick: bool, seed: int = 0) -> Figure:
    sc = sweep_scale(quick)
    imgs = E.load_images(sc["images"])
    rows = []
    assumed = FIG9_ASSUMED_MM[::2] if quick else FIG9_ASSUMED_MM
    for Za in assumed:
        cam = prototype(object_depth_mm=Za, side="near")  # the far side is impossible past ~750 mm
        k_assumed = P.design_psf(cam, "coded", 0.0)
        depths = Za * np.geomspace(0.8, 1.25, sc["depths"])
        kernels = [P.design_psf(cam.with_(object_depth_mm=float(Z)), "coded", 0.0) for Z in depths]
        scenes = E.Scenes(imgs, pad_for([k_assumed, *kernels]))
        for Z, k in zip(depths, kernels):
            p = E.simulate(scenes, k, k_assumed, E.gaussian_noise(SIGMA), seed, margin_px=16)
            m, se = mean_sem(p)
            cz = cam.with_(object_depth_mm=float(Z))
            rows.append(
                {
                    "assumed_depth_mm": Za,
                    "depth_mm": float(Z),
                    "displacement": float(Z / Za),
                    "r_px": cz.r_px,
                    "a_i_px_per_ms2": cz.a_i_px_per_ms2,
                    "psnr_db": m,
                    "psnr_sem_db": se,
                }
            )
    return Figure("fig9", rows, lambda path: _plot_fig9(rows, path), _summary_fig9(rows))


def _by_assumed(rows):
    out = {}
    for r in rows:
        out.setdefault(r["assumed_depth_mm"], []).append((r["depth_mm"], r["psnr_db"]))
    return {k: np.array(v) for k, v in out.items()}


def tolerated_range_mm(curve: np.ndarray, drop_db: float = 1.0) -> tuple[float, float]:
    """Depths where PSNR stays within drop_db of the peak, interpolated linearly in log depth."""
    lz, p = np.log(curve[:, 0]), curve[:, 1]
    level = p.max() - drop_db
    k = int(np.argmax(p))
    lo, hi = lz[0], lz[-1]
    for i in range(k, 0, -1):
        if p[i - 1] < level:
            lo = lz[i - 1] + (level - p[i - 1]) / (p[i] - p[i - 1]) * (lz[i] - lz[i - 1])
            break
    for i in range(k, lz.size - 1):
        if p[i + 1] < level:
            hi = lz[i] + (p[i] - level) / (p[i] - p[i + 1]) * (lz[i + 1] - lz[i])
            break
    return float(np.exp(lo)), float(np.exp(hi))


def peak_gap_db(curve: np.ndarray, assumed_mm: float) -> float:
    """Best PSNR minus PSNR at the assumed depth, dB (0 when the peak is there)."""
    at = curve[np.argmin(np.abs(np.log(curve[:, 0] / assumed_mm))), 1]
    return float(curve[:, 1].max() - at)


def _plot_fig9(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for Za, c in _by_assumed(rows).items():
        (line,) = ax.semilogx(c[:, 0], c[:, 1], "o-", ms=3, label=f"assumed {Za:g} mm")
        ax.axvline(Za, ls=":", color=line.get_color())
    ax.set_xlabel("object depth (mm, log)")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title("Fig. 9: PSNR vs object depth, deconvolved with the assumed-depth PSF")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    save_fig(fig, path)


def _summary_fig9(rows) -> str:
    lines = [
        "| assumed depth (mm) | best depth (mm) | PSNR gap at assumed (dB) | 1-dB range (mm) "
        "| range / assumed |",
        "|---|---|---|---|---|",
    ]
    widths, gaps = [], []
    for Za, c in _by_assumed(rows).items():
        lo, hi = tolerated_range_mm(c)
        widths.append((hi - lo) / Za)
        gaps.append(peak_gap_db(c, Za))
        zpk = c[np.argmax(c[:, 1]), 0]
        lines.append(
            f"| {Za:g} | {zpk:.0f} | {gaps[-1]:.2f} | {lo:.0f}-{hi:.0f} | {widths[-1]:.3f} |"
        )
    agree = max(gaps) < 0.25 and widths[-1] > widths[0]
    return "\n".join(
        [
            "# Fig. 9: PSNR vs object depth",
            "",
            "**Paper:** PSNR peaks where the object is at the assumed depth; the tolerated range is "
            "narrow near the camera and wider far away, like depth of field.",
            "",
            f"**Ours:** PSNR at the assumed depth is within {max(gaps):.2f} dB of each curve's best; "
            f"the 1-dB range grows from {widths[0]:.3f} to {widths[-1]:.3f} of the assumed depth. "
            f"**{'Agrees' if agree else 'Differs'}.**",
            "",
            "Why it widens: r and a_i depend on depth through 1/Z (Eqs. 9, 12, 18), so a fixed "
            "relative displacement changes them less when Z is large. Why the best depth can sit "
            "slightly nearer than the assumed one far away: there the curve is flat, and an object "
            "closer to the focal plane is captured sharper (smaller r), which can outweigh the small "
            "PSF mismatch. Nearer than the focal plane itself, beta changes sign, the parabola is "
            "mirrored and PSNR collapses.",
            "",
            "Set-up: the prototype refocused for each assumed depth so that r = 2 px there "
            "(focus in front of the objects: beyond about 750 mm a 2-px blur cannot be made by "
            "focusing behind them), s = 0, 16 patterns, Gaussian sigma = 0.01.",
            "",
            *lines,
        ]
    )
