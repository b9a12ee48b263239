"""``pacam reproduce``: the paper's simulation figures (Figs. 6-9), each as CSV, PNG and a
Markdown summary that sets the paper's claim beside our numbers.

Shared set-up (Section 3): scikit-image photographs instead of the paper's 30 Flickr images
(:data:`pacam_render.experiments.IMAGE_NAMES`), Wiener deconvolution, Gaussian noise sigma = 0.01
on [0, 1] images unless the photon budget matters, exposure 2T = 45 ms, r = 2 px unless swept.
Every curve is computed twice where it matters: with the paper's continuous model (Eq. 14) and
with the 16 held patterns the camera really shows.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..io.outputs import csv_text, save_figure, write_text
from ..model import paper
from ..model.camera import prototype
from ..psf import analytic as P
from . import simulate as E

T_MS = 0.5 * paper.EXPOSURE_MS
SIGMA = 0.01
R_PX = 2.0
MODELS = {"Eq. 14 (continuous)": "continuous", "16 patterns (camera)": "discrete"}


@dataclass
class Figure:
    """One reproduced figure: its rows, its plot and its summary."""

    name: str
    rows: list[dict]
    plot: Callable[[Path], None]
    summary: str
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)


def _scale(quick: bool) -> dict:
    return (
        {"images": 4, "speeds": 8, "radii": 7, "depths": 9}
        if quick
        else {"images": None, "speeds": 20, "radii": 14, "depths": 21}
    )


def coded_kernel(model: str, s: float, a: float, r: float, n: int = paper.N_PATTERNS) -> np.ndarray:
    if model == "continuous":
        return P.coded_psf(s, a, r, T_MS)
    return P.discrete_coded_psf(s, a, r, T_MS, n)


def _pad_for(kernels: list[np.ndarray]) -> int:
    return max(max(k.shape) for k in kernels) // 2 + 1


def _mean_sem(v: np.ndarray) -> tuple[float, float]:
    return E.summarise(v)


# --- Fig. 6 -------------------------------------------------------------------------------------
FIG6_A = (0.008, 0.016, 0.032, 0.064, 0.128, 0.256)


def fig6(quick: bool, seed: int = 0) -> Figure:
    sc = _scale(quick)
    imgs = E.load_images(sc["images"])
    speeds = np.geomspace(0.01, 4.0, sc["speeds"])
    rows = []
    for label, model in MODELS.items():
        for a in FIG6_A:
            k0 = coded_kernel(model, 0.0, a, R_PX)
            ks = [coded_kernel(model, s, a, R_PX) for s in speeds]
            scenes = E.Scenes(imgs, _pad_for([k0, *ks]))
            for s, k in zip(speeds, ks):
                p = E.simulate(scenes, k, k0, E.gaussian_noise(SIGMA), seed, margin_px=16)
                m, se = _mean_sem(p)
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
    _save_fig(fig, path)


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


# --- photon budgets -----------------------------------------------------------------------------
F_MIN = paper.F_MIN
SHORT_MS = paper.SHORT_EXPOSURE_MS
EXPOSURE_MS = paper.EXPOSURE_MS


def f_number_for(a_i: float, r_px: float) -> float:
    """The F-number that gives a_i with defocus r (Eq. 18): N = N_min (1 + a_i T^2 / 4r)."""
    return F_MIN * (1.0 + a_i * T_MS**2 / (4.0 * r_px))


def light(f_number: float, exposure_ms: float) -> float:
    """Collected light relative to F2.8 for 1 ms (open area x time)."""
    return (F_MIN / f_number) ** 2 * exposure_ms


def paper_noise(sigma: float) -> E.NoiseFn:
    """The paper's Gaussian noise through the ``paper`` sensor preset (read noise only)."""
    from ..sensor.model import SensorModel

    model = SensorModel.from_preset("paper", sigma=float(sigma))
    return E.sensor_noise(model, model.full_well_e, EXPOSURE_MS)


# --- Fig. 7 -------------------------------------------------------------------------------------
FIG7_A = (0.025, 0.05, 0.1)
FIG7_PAPER_PEAK = {0.025: 1.0, 0.05: 2.5, 0.1: 3.5}
SPEED_FRACTIONS = (0.0, 0.5, 1.0)  # of the invariant range a_i T


def fig7(quick: bool, seed: int = 0) -> Figure:
    sc = _scale(quick)
    imgs = E.load_images(sc["images"])
    radii = np.geomspace(0.5, 6.0, sc["radii"])
    ref_light = light(9.85, EXPOSURE_MS)  # sigma = 0.01 at the prototype's F9.85, 45 ms
    rows = []
    for a in FIG7_A:
        for r in radii:
            N = f_number_for(a, r)
            sigma = SIGMA * ref_light / light(N, EXPOSURE_MS)  # read-noise limited: 1 / light
            k0 = coded_kernel("discrete", 0.0, a, r)
            ks = [coded_kernel("discrete", f * a * T_MS, a, r) for f in SPEED_FRACTIONS]
            scenes = E.Scenes(imgs, _pad_for([k0, *ks]))
            p = np.mean([E.simulate(scenes, k, k0, paper_noise(sigma), seed, 16) for k in ks], 0)
            m, se = _mean_sem(p)
            rows.append(
                {
                    "a_i_px_per_ms2": a,
                    "r_px": float(r),
                    "f_number": N,
                    "noise_sigma": sigma,
                    "psnr_db": m,
                    "psnr_sem_db": se,
                }
            )
    return Figure("fig7", rows, lambda path: _plot_fig7(rows, path), _summary_fig7(rows))


def peak_radius_px(curve: np.ndarray) -> float:
    """r of the PSNR peak, refined by a parabola in log r through the best point's neighbours."""
    lr, p = np.log(curve[:, 0]), curve[:, 1]
    k = int(np.argmax(p))
    if 0 < k < p.size - 1:
        x, y = lr[k - 1 : k + 2], p[k - 1 : k + 2]
        c2, c1, _ = np.polyfit(x, y, 2)
        if c2 < 0:
            return float(np.exp(np.clip(-c1 / (2 * c2), x[0], x[-1])))
    return float(curve[k, 0])


def _fig7_curves(rows):
    out = {}
    for r in rows:
        out.setdefault(r["a_i_px_per_ms2"], []).append((r["r_px"], r["psnr_db"]))
    return {a: np.array(v) for a, v in out.items()}


def _plot_fig7(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for a, c in _fig7_curves(rows).items():
        (line,) = ax.plot(c[:, 0], c[:, 1], "o-", ms=3, label=f"a_i = {a:g}")
        ax.axvline(peak_radius_px(c), ls=":", color=line.get_color())
    ax.set_xlabel("static PSF radius r (px)")
    ax.set_ylabel("PSNR (dB)")
    ax.set_title("Fig. 7: PSNR vs static PSF radius (dotted: our peaks)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    _save_fig(fig, path)


def _summary_fig7(rows) -> str:
    lines = [
        "| a_i | paper's peak r (px) | our peak r (px) | F-number there | peak PSNR (dB) |",
        "|---|---|---|---|---|",
    ]
    peaks = []
    for a, c in _fig7_curves(rows).items():
        rp = peak_radius_px(c)
        peaks.append(rp)
        lines.append(
            f"| {a:g} | {FIG7_PAPER_PEAK[a]:g} | {rp:.2f} | {f_number_for(a, rp):.1f} | "
            f"{c[:, 1].max():.2f} |"
        )
    rising = all(np.diff(peaks) > 0)
    return "\n".join(
        [
            "# Fig. 7: PSNR vs static PSF radius",
            "",
            "**Paper:** the PSNR curve has an interior peak, at r = 1, 2.5 and 3.5 px for "
            "a_i = 0.025, 0.05 and 0.1 px/ms^2: the best defocus grows with the acceleration.",
            "",
            f"**Ours:** peaks at r = {', '.join(f'{p:.2f}' for p in peaks)} px. The peak "
            f"{'moves to larger r with a_i, as in the paper' if rising else 'does not grow with a_i'}. "
            f"**{'Agrees in trend' if rising else 'Differs'}**; the positions depend on the noise "
            "reference below, which the paper does not state.",
            "",
            "Why there is a peak: at fixed a_i, Eq. 18 ties r to the opening, "
            "R = R_max / (1 + a_i T^2 / 4r). A small r forces a small opening, so little light and "
            "much noise; a large r lets in light but blurs more. The noise is read-noise limited "
            "(the paper's Gaussian model), so its sigma on the [0, 1] image scales as 1 / light, "
            "with sigma = 0.01 at the prototype's F9.85 and 45 ms.",
            "",
            "Set-up: 16 patterns, PSNR averaged over s = 0, a_i T / 2 and a_i T, noise through the "
            "`paper` sensor preset.",
            "",
            *lines,
        ]
    )


# --- Fig. 8 -------------------------------------------------------------------------------------
FIG8_CURVES = ("proposed", "Levin (same aperture)", "Levin (full aperture)")


def _fig8_mse(scenes, k_cap, k_dec, noise, seed) -> np.ndarray:
    if k_dec is None:  # the short exposure is not deconvolved: its own image is the estimate
        rng = np.random.default_rng(seed)
        noisy, _ = noise(scenes.blurred(k_cap), rng)
        return 10 ** (-E.psnr_batch(noisy, scenes.images, 16) / 10)
    return 10 ** (-E.simulate(scenes, k_cap, k_dec, noise, seed, 16) / 10)


def fig8(quick: bool, seed: int = 0) -> Figure:
    sc = _scale(quick)
    imgs = E.load_images(sc["images"])
    sigmas = np.geomspace(5e-4, 0.05, 6 if quick else 13)
    rows = []
    for a in FIG7_A:
        r = FIG7_PAPER_PEAK[a]
        N = f_number_for(a, r)
        coded_light = light(N, EXPOSURE_MS)
        budgets = {
            "proposed": 1.0,
            "Levin (same aperture)": 1.0,
            "Levin (full aperture)": light(F_MIN, EXPOSURE_MS) / coded_light,
            "short exposure": light(F_MIN, SHORT_MS) / coded_light,
        }
        speeds = [f * a * T_MS for f in SPEED_FRACTIONS]
        kernels = {
            "proposed": (
                [coded_kernel("discrete", s, a, r) for s in speeds],
                coded_kernel("discrete", 0, a, r),
            ),
            "Levin": ([P.levin_psf(s, a, T_MS) for s in speeds], P.levin_psf(0.0, a, T_MS)),
            "short exposure": ([P.short_exposure_psf(s, SHORT_MS) for s in speeds], None),
        }
        pad = _pad_for(
            [k for ks, k0 in kernels.values() for k in [*ks] + ([k0] if k0 is not None else [])]
        )
        scenes = E.Scenes(imgs, pad)
        for sigma in sigmas:
            mse = {}
            for curve, budget in budgets.items():
                ks, k0 = kernels["Levin" if curve.startswith("Levin") else curve]
                noise = paper_noise(sigma / budget)  # read-noise limited: sigma ~ 1 / light
                mse[curve] = np.mean([_fig8_mse(scenes, k, k0, noise, seed).mean() for k in ks])
            for curve in FIG8_CURVES:
                rows.append(
                    {
                        "a_i_px_per_ms2": a,
                        "r_px": r,
                        "f_number": N,
                        "curve": curve,
                        "noise_level": float(sigma),
                        "mse": mse[curve],
                        "mse_short": mse["short exposure"],
                        "quality_ratio": float(np.sqrt(mse["short exposure"] / mse[curve])),
                    }
                )
    return Figure("fig8", rows, lambda path: _plot_fig8(rows, path), _summary_fig8(rows))


def _fig8_curves(rows):
    out = {}
    for r in rows:
        out.setdefault((r["curve"], r["a_i_px_per_ms2"]), []).append(
            (r["noise_level"], r["quality_ratio"])
        )
    return {k: np.array(v) for k, v in out.items()}


def crossing_noise_level(curve: np.ndarray) -> float:
    """Noise level where the quality ratio first crosses 1 (log-linear interpolation), or nan."""
    x, y = np.log(curve[:, 0]), curve[:, 1]
    for i in range(len(y) - 1):
        if (y[i] - 1) * (y[i + 1] - 1) <= 0 and y[i] != y[i + 1]:
            return float(np.exp(x[i] + (1 - y[i]) / (y[i + 1] - y[i]) * (x[i + 1] - x[i])))
    return float("nan")


def _plot_fig8(rows, path: Path) -> None:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    styles = {"proposed": "-", "Levin (same aperture)": "--", "Levin (full aperture)": ":"}
    colors = {}
    for (curve, a), c in _fig8_curves(rows).items():
        kw = {"color": colors[a]} if a in colors else {}
        (line,) = ax.loglog(
            c[:, 0], c[:, 1], styles[curve], marker="o", ms=3, label=f"{curve}, a_i = {a:g}", **kw
        )
        colors.setdefault(a, line.get_color())
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xlabel("noise level (sigma of the coded capture, [0, 1] scale)")
    ax.set_ylabel("quality ratio sqrt(MSE_short / MSE)")
    ax.set_title(f"Fig. 8: quality vs a short exposure ({SHORT_MS} ms at F{F_MIN:g})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=1)
    _save_fig(fig, path)


def _summary_fig8(rows) -> str:
    curves = _fig8_curves(rows)
    lines = [
        "| curve | a_i | F-number | ratio at lowest noise | ratio at highest | crosses 1 at |",
        "|---|---|---|---|---|---|",
    ]
    cross = {}
    for (curve, a), c in curves.items():
        cross[(curve, a)] = crossing_noise_level(c)
        N = next(r["f_number"] for r in rows if r["a_i_px_per_ms2"] == a)
        lines.append(
            f"| {curve} | {a:g} | {N:.1f} | {c[0, 1]:.2f} | {c[-1, 1]:.2f} | "
            f"{cross[(curve, a)]:.4f} |"
        )
    prop = [v for (cv, _), v in cross.items() if cv == "proposed"]
    rising = all(
        np.all(np.diff(c[:, 1]) > -0.05) and c[-1, 1] > 1 > c[0, 1]
        for (cv, _), c in curves.items()
        if cv == "proposed"
    )
    near = min(
        (r for r in rows if r["curve"] == "proposed" and r["a_i_px_per_ms2"] == 0.05),
        key=lambda r: abs(np.log(r["noise_level"] / 0.004)),
    )
    levin_higher = all(
        curves[("Levin (same aperture)", a)][-1, 1] > curves[("proposed", a)][-1, 1] for a in FIG7_A
    )
    return "\n".join(
        [
            "# Fig. 8: quality ratio against a short exposure",
            "",
            "**Paper:** sqrt(MSE_short / MSE) rises with the noise level; the proposed method and "
            "Levin's beat the short exposure beyond a noise level of about 0.004, Levin's by much more "
            "(it has no defocus).",
            "",
            f"**Ours:** the proposed method crosses 1 at noise levels {', '.join(f'{v:.4f}' for v in prop)} "
            f"for a_i = {', '.join(f'{a:g}' for a in FIG7_A)}; Levin's ratio is higher "
            f"({'yes' if levin_higher else 'no'}). **{'Agrees in shape' if rising and levin_higher else 'Differs'}**, "
            f"but the crossing sits {np.nanmedian(prop) / 0.004:.1f}x above the paper's 0.004. "
            f"At a noise level of {near['noise_level']:.4f} (a_i = {near['a_i_px_per_ms2']:g}) the "
            f"deconvolved coded capture reaches {-10 * np.log10(near['mse']):.1f} dB and the short "
            f"exposure {-10 * np.log10(near['mse_short']):.1f} dB: the short exposure's only defect "
            "there is its noise, while deconvolution leaves an error floor (defocus, motion code, "
            "aligned tails) that does not shrink with the noise. The paper's crossing needs a lower "
            "floor than ours; its images (30 Flickr photographs of unstated size) and its Wiener "
            "setting are not stated, so we cannot say which. Levin's lead at equal light is small "
            "here; the physical Levin camera (full aperture) leads clearly, by its extra light.",
            "",
            "How the paper's noise level maps to photons: it is the read-noise sigma of the coded "
            "capture on its [0, 1] scale (the paper's Gaussian model, the `paper` sensor preset). "
            "Every other capture gets the same read noise in electrons but its own light: its sigma "
            "on its own [0, 1] scale is the noise level times (coded light / its light). The short "
            f"exposure ({SHORT_MS} ms at F2.8) collects (45 / {SHORT_MS}) (2.8 / N)^2 = 3.8-5.4x less "
            "light than a coded capture at F-number N, so its sigma is that much larger. "
            "'Levin (same aperture)' isolates the defocus penalty, as the paper explains it; "
            "'Levin (full aperture)' is the physical camera, whose body motion needs no stopping "
            "down, and gains (N / 2.8)^2 more light on top.",
            "",
            "Set-up: r = 1, 2.5, 3.5 px for a_i = 0.025, 0.05, 0.1 (the paper's Fig. 7 optima), "
            "the F-number from Eq. 18, 16 patterns, MSE averaged over s = 0, a_i T / 2 and a_i T; "
            "the short exposure is not deconvolved.",
            "",
            *lines,
        ]
    )


# --- Fig. 9 -------------------------------------------------------------------------------------
FIG9_ASSUMED_MM = (300.0, 500.0, 1000.0, 2000.0, 3000.0)


def fig9(quick: bool, seed: int = 0) -> Figure:
    sc = _scale(quick)
    imgs = E.load_images(sc["images"])
    rows = []
    assumed = FIG9_ASSUMED_MM[::2] if quick else FIG9_ASSUMED_MM
    for Za in assumed:
        cam = prototype(object_depth_mm=Za, side="near")  # the far side is impossible past ~750 mm
        k_assumed = P.design_psf(cam, "coded", 0.0)
        depths = Za * np.geomspace(0.8, 1.25, sc["depths"])
        kernels = [P.design_psf(cam.with_(object_depth_mm=float(Z)), "coded", 0.0) for Z in depths]
        scenes = E.Scenes(imgs, _pad_for([k_assumed, *kernels]))
        for Z, k in zip(depths, kernels):
            p = E.simulate(scenes, k, k_assumed, E.gaussian_noise(SIGMA), seed, margin_px=16)
            m, se = _mean_sem(p)
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
    _save_fig(fig, path)


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


# --- train scene (Figs. 12-15) ------------------------------------------------------------------
def fig_train(quick: bool, seed: int = 0) -> Figure:
    """Rendered captures of the train set, deblurred with analytic and rendered PSFs."""
    import tempfile

    from ..restore.metrics import aligned_psnr, psnr, ssim
    from .demo import Coded, _figure, max_shift_px, run_train, window_crops

    w, h, spp, spp_psf = (320, 240, 64, 256) if quick else (640, 480, 256, 1024)
    coded = (
        Coded("prototype (r = 2 px, a_i = 0.040)"),
        Coded("quoted a_i = 0.089 (r = 4.5 px)", 2.0),
    )
    with tempfile.TemporaryDirectory() as tmp:
        _, panels, caps = run_train(
            Path(tmp),
            w,
            h,
            spp,
            seed,
            coded,
            rendered_psf=True,
            spp_psf=spp_psf,
            name="train",
            method="wiener",
        )
    ref = caps["reference"].image
    crops, shift = window_crops(caps["_spec"]), max_shift_px(caps["_spec"])
    rows = []
    for p in panels[1:]:
        rows.append(
            {
                "capture": p.title,
                "region": "full frame (not aligned)",
                "psnr_db": psnr(p.image, ref, 1.0),
                "ssim": ssim(p.image, ref),
            }
        )
        for cname, frac in crops.items():
            rows.append(
                {
                    "capture": p.title,
                    "region": f"{cname} (aligned)",
                    "psnr_db": aligned_psnr(p.image, ref, frac, shift),
                    "ssim": float("nan"),
                }
            )
    return Figure(
        "train",
        rows,
        lambda path: _figure(panels, ref, path, crops, shift),
        _summary_train(rows, w, h, spp, spp_psf, caps),
    )


def _fmt_ssim(v: float) -> str:
    return "" if np.isnan(v) else f"{v:.3f}"


def _summary_train(rows, w, h, spp, spp_psf, caps) -> str:
    table = ["| capture | region | PSNR (dB) | SSIM |", "|---|---|---|---|"]
    table += [
        f"| {r['capture']} | {r['region']} | {r['psnr_db']:.2f} | {_fmt_ssim(r['ssim'])} |"
        for r in rows
    ]

    def get(capture, region):
        return next(
            r["psnr_db"]
            for r in rows
            if r["capture"].startswith(capture) and r["region"].startswith(region)
        )

    q = "quoted a_i = 0.089"
    near_coded = get(f"coded, {q}", "near train")
    near_dec = get(f"deconvolved (analytic PSF), {q}", "near train")
    near_rend = get(f"deconvolved (rendered PSF), {q}", "near train")
    near_normal = get("normal", "near train")
    return "\n".join(
        [
            "# Train scene: normal, coded, deconvolved and short captures (Figs. 12-15)",
            "",
            "**Paper:** the coded capture blurs everything; deconvolution with one measured PSF "
            "removes the motion blur of both trains and the defocus of the static background; "
            "the short exposure is sharp but noisy.",
            "",
            f"**Ours:** with the published prototype (a_i = 0.040 px/ms^2 by Eq. 18, invariant "
            "range 0.9 px/ms) the trains (1.0 and 1.4 px/ms) lie outside the range and stay "
            "blurred; with the paper's quoted a_i = 0.089 (which needs r = 4.5 px at F9.85 in "
            f"45 ms), the near train goes from {near_normal:.1f} dB (normal) and {near_coded:.1f} "
            f"dB (coded) to {near_dec:.1f} dB deconvolved with the analytic PSF and "
            f"{near_rend:.1f} dB with the rendered one. "
            + (
                "**Agrees** for the quoted a_i; the published optics alone cannot deliver it."
                if near_dec > near_coded + 1.0
                else f"**Differs in size:** the gain is only {near_dec - near_coded:.1f} dB, "
                "though the windows and wheels reappear in the crops: the sensor and Monte "
                "Carlo noise that Wiener must not amplify cap it, and at a_i = 0.089 the 16 "
                "held patterns jump by several pixels (Fig. 6's dips)."
            )
            + f" The static backdrop goes from {get('coded, prototype', 'backdrop'):.1f} dB "
            f"(coded) to {get('deconvolved (analytic PSF), prototype', 'backdrop'):.1f} dB "
            "(deconvolved): Wiener assumes white noise, and a demosaicked Bayer capture's noise "
            "is neither white nor equal across colours, so the filter's balance is only "
            "approximate here (BM3D deblurring, the paper's choice, is `--method bm3d`).",
            "",
            "Alignment: a motion-invariant PSF moves each object by -s^2 / (2 a_i) (the trains by "
            "different amounts, the background not at all), so each crop is scored at its best "
            "whole-pixel horizontal shift within +-12 px; full-frame numbers are not aligned.",
            "",
            f"Set-up: {w}x{h} px, {spp} spp, the Grasshopper/ICX285 sensor model at 300 "
            "photons/px/ms (white, F2.8), Wiener with the sensor's noise sigma; the rendered PSF "
            f"is a ptracer render of a point at 500 mm ({spp_psf} spp per pattern window), "
            "registered like the analytic one. References are pinhole renders with motion frozen "
            "at mid-exposure.",
            "",
            *table,
        ]
    )


# --- writing ------------------------------------------------------------------------------------
def _save_fig(fig, path: Path) -> None:

    fig.tight_layout()
    save_figure(fig, path, 110)


FIGURES: dict[str, Callable[[bool, int], Figure]] = {
    "fig6": fig6,
    "fig7": fig7,
    "fig8": fig8,
    "fig9": fig9,
    "train": fig_train,
}


def run(
    names: list[str],
    out: Path,
    quick: bool,
    force: bool,
    seed: int = 0,
    workers: int = 0,
    scheduler: str | None = None,
) -> list[Figure]:
    """Compute and write each figure: NAME.csv, NAME.png, NAME.md in ``out``.

    Each figure is one task of :func:`compute_figure` on the study engine
    (:func:`~pacam_render.study.engine.run_tasks`: ``workers`` processes of a LocalCluster,
    0 for serial, or an existing Dask ``scheduler``); files are written here as each ends.
    """
    import matplotlib

    from ..study.engine import run_tasks

    matplotlib.use("Agg")
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        raise ParameterError(f"unknown figure {unknown}; valid: {', '.join(FIGURES)}, all")
    for n in names:  # refuse before computing anything
        for ext in ("csv", "png", "md"):
            if (out / f"{n}.{ext}").exists() and not force:
                raise ParameterError(f"{out / f'{n}.{ext}'} exists; pass --force to overwrite it")
    done: dict[str, Figure] = {}

    def write(task, fig) -> None:
        if isinstance(fig, BaseException):
            raise fig
        write_text(out / f"{fig.name}.csv", csv_text(fig.rows), force=True)
        fig.plot(out / f"{fig.name}.png")
        stamp = f"\n\nComputed in {fig.seconds:.1f} s ({'--quick' if quick else 'full'} run).\n"
        write_text(out / f"{fig.name}.md", fig.summary + stamp, force=True)
        done[fig.name] = fig

    run_tasks(compute_figure, [(n, quick, seed) for n in names], write, workers, scheduler)
    return [done[n] for n in names]


def compute_figure(task) -> Figure:
    """Figure ``name`` computed (a task: (name, quick, seed)), with its time in ``seconds``."""
    import matplotlib

    matplotlib.use("Agg")
    name, quick, seed = task
    t0 = time.perf_counter()
    fig = FIGURES[name](quick, seed)
    fig.seconds = time.perf_counter() - t0
    return fig
