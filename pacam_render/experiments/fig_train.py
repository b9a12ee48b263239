"""The train scene of Figs. 12-15, rendered and deblurred (:mod:`.demo`), as a reproduced
figure: PSNR and SSIM of each capture against its pinhole reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..restore.metrics import aligned_psnr, psnr, ssim
from .demo import Coded, _figure, max_shift_px, run_train, window_crops
from .figures import Figure


def fig_train(quick: bool, seed: int = 0) -> Figure:
    """Rendered captures of the train set, deblurred with analytic and rendered PSFs."""
    import tempfile

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
            "approximate here (BM3D deblurring, the paper's choice, is the `bm3d` method).",
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
