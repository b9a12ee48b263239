"""Diffraction at the aperture (issue 36, item 1): kernel error against run time, and the
error of the defocus + diffraction combination against the exact Fourier-optics PSF.

Tables (each printed and appended to benchmarks/RESULTS.md):

1. Fraunhofer kernels of the disc at F9.85 and F2.8 (550 nm, 6.45 um pixels) for a range of
   ``max_lost``: size, light left out, the stated alias estimate and the alias measured (the
   window against a 2x longer period), seconds, and the image-level effect of the truncation:
   RMS change of skimage's ``camera`` (512 x 512, white = 1) blurred with the kernel against
   the same blurred with a kernel that leaves out 0.05 %.
2. Bitmaps and stiff cases: the prototype's 16 rasterised LCoS discs, one LCoS pixel.
3. Defocus + diffraction: L1 of the simulator's combination (pillbox_psf convolved with the
   pixel-integrated Airy kernel), of the exact continuous combination, and of the pillbox
   alone, to the exact PSF |FT(P exp(i psi rho^2))|^2, for r = 0, 0.5, 1, 2, 4 px at F9.85.
4. One wavelength per colour channel against the channel's band (11 wavelengths over
   +-50 nm around it, equal weights): kernel L1 and image RMS.
5. The capture post-process (:mod:`pacam_render.wave.image`): a geometric capture convolved
   with the band kernel (or the pixel-integrated one), against a reference with diffraction
   before the pixel, 8x finer (:mod:`pacam_render.wave.supersampled`), on a slanted edge and
   a dead-leaves scene, in focus and at r = 2 px; seconds per megapixel and channel; and the
   must-show edge MTF ratio.
6. Box-once kernels (:func:`~pacam_render.psf.diffraction.diffracted_kernel`): the fine grid
   against the kernel's error (L1 to the same kernel on a 21x grid, near the continuous
   limit) and its run time, for the coded, the fluttered shutter's and the normal capture at
   0.4 px/ms, per channel wavelength; the default grid (``supersample``) is marked.

    python benchmarks/bench_diffraction.py [--quick] [--only TABLE]
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import numpy as np
from common import record
from scipy.signal import fftconvolve
from skimage import data, transform

from pacam_render.model.camera import prototype
from pacam_render.model.masks import MaskStack, disc_masks
from pacam_render.psf.combination import COMPARISON_SIZE, combination_error
from pacam_render.wave.defocus import pillbox_otf
from pacam_render.wave.edge_mtf import edge_mtf
from pacam_render.wave.fraunhofer import fraunhofer_kernel, kernel_from_otf, periodic_kernel
from pacam_render.wave.image import diffract_image
from pacam_render.wave.otf import disc_otf, pupil_otf
from pacam_render.wave.patterns import CHANNEL_WAVELENGTHS_NM, mode_diffraction_kernel
from pacam_render.wave.pupil import DiscPupil, mask_pupil
from pacam_render.wave.reference import circular_mtf
from pacam_render.wave.scale import DiffractionScale
from pacam_render.wave.supersampled import supersampled_capture

LCOS = 0.01362
D = 2 * 2.8 * 512 * LCOS
S550 = DiffractionScale(550.0, 0.00645, D)
OPENINGS = {"F9.85": 145.5 * LCOS, "F2.8": 512 * LCOS}


def image() -> np.ndarray:
    return transform.resize(data.camera() / 255.0, (512, 512), anti_aliasing=True)


def blur(img: np.ndarray, k: np.ndarray) -> np.ndarray:
    h = k.shape[0] // 2
    return fftconvolve(np.pad(img, h, mode="reflect"), k, mode="valid")


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def kernel_table(img: np.ndarray, quick: bool) -> None:
    rows = []
    for name, R in OPENINGS.items():
        ref = fraunhofer_kernel(DiscPupil(R), S550, max_lost=5e-4).kernel
        sharp_ref = blur(img, ref)
        for max_lost in (0.01, 0.005, 0.002) if quick else (0.01, 0.005, 0.002, 0.001):
            d, sec = timed(
                lambda R=R, m=max_lost: fraunhofer_kernel(DiscPupil(R), S550, max_lost=m)
            )
            h = d.kernel.shape[0] // 2
            big = periodic_kernel(pupil_otf(DiscPupil(R), S550), 2 * d.period_px)
            c = d.period_px
            win = big[c - h : c + h + 1, c - h : c + h + 1]
            rows.append(
                {
                    "opening": name,
                    "max_lost": max_lost,
                    "size px": d.kernel.shape[0],
                    "lost": d.lost,
                    "alias estimate": d.alias,
                    "alias measured (L1)": float(np.abs(d.kernel * (1 - d.lost) - win).sum()),
                    "period px": d.period_px,
                    "kernel s": sec,
                    "truncation RMS on camera": rms(blur(img, d.kernel), sharp_ref),
                    "diffraction RMS on camera": rms(sharp_ref, img),
                }
            )
    record(
        "Diffraction kernels: Fraunhofer disc kernels, error against run time (issue 36)",
        rows,
        "550 nm, 6.45 um pixels, the paper's F-number scale (D = 2 F_min R_max). 'lost': light "
        "outside the kernel (renormalised, so the kernel's L1 error is 2 lost); 'alias "
        "measured': L1 of the un-normalised window against the same window of a 2x longer "
        "period (aliasing falls ~ L^-2, so this is ~3/4 of it). RMS on skimage's camera "
        "(512x512, white = 1) against a kernel that leaves out 0.05 %; 'diffraction RMS' is "
        "the effect of diffraction itself. One shared core.",
    )


def stiff_table() -> None:
    rows = []
    cam = prototype()
    stack = MaskStack(disc_masks(cam.pattern_centres_xy_mm(), cam.R_mm, pitch_mm=LCOS), LCOS)
    bitmap = cam.with_(pattern_masks=stack)
    d, sec = timed(lambda: mode_diffraction_kernel(bitmap, "coded", 550.0))
    ideal = fraunhofer_kernel(DiscPupil(cam.R_mm), S550, size=d.kernel.shape[0]).kernel
    rows.append(
        {
            "case": "prototype: 16 rasterised LCoS discs (coded, bitmap schedule)",
            "size px": d.kernel.shape[0],
            "lost": d.lost,
            "seconds": sec,
            "L1 to the ideal disc's kernel": float(np.abs(d.kernel - ideal).sum()),
        }
    )
    one = np.zeros((1024, 1280))
    one[500, 600] = 1.0
    pupil = mask_pupil(one, LCOS)
    t0 = time.perf_counter()
    try:
        fraunhofer_kernel(pupil, S550)
        refused = "no"
    except Exception as exc:  # noqa: BLE001 - the refusal is the point
        refused = type(exc).__name__
    rows.append(
        {
            "case": f"one LCoS pixel, default max_lost: refused ({refused})",
            "size px": "-",
            "lost": "-",
            "seconds": time.perf_counter() - t0,
            "L1 to the ideal disc's kernel": "-",
        }
    )
    d, sec = timed(lambda: fraunhofer_kernel(pupil, S550, size=2049, max_lost=0.1))
    rows.append(
        {
            "case": "one LCoS pixel, size 2049, max_lost 0.1",
            "size px": 2049,
            "lost": d.lost,
            "seconds": sec,
            "L1 to the ideal disc's kernel": "-",
        }
    )
    record(
        "Diffraction kernels of bitmaps and stiff openings (issue 36)",
        rows,
        "550 nm. The one-pixel opening's central lobe spans +-244 px; its 1/h tail needs "
        "~50 000 px to keep all but 0.2 % of the light, so the default refuses before any work.",
    )


def combination_table() -> list[dict]:
    rows = []
    for r in (0.0, 0.5, 1.0, 2.0, 4.0):
        e = combination_error(OPENINGS["F9.85"], r, S550)
        rows.append(
            {
                "r px": r,
                "W020 waves": e["w020_waves"],
                "L1 simulator (pillbox_psf * Airy kernel)": e["l1_simulator"],
                "L1 continuous combination": e["l1_continuous"],
                "L1 pillbox alone (no diffraction)": e["l1_geometric"],
                "exact kernel s": e["seconds"],
            }
        )
    record(
        "Defocus + diffraction: the combination against the exact Fourier-optics PSF (issue 36)",
        rows,
        f"F9.85 (the 145.5 LCoS px disc), 550 nm, 6.45 um pixels; {COMPARISON_SIZE}x"
        f"{COMPARISON_SIZE} normalised, pixel-integrated kernels. Exact: |FT(P exp(i psi "
        "rho^2))|^2 with W020 = r p / (4N) (geometric blur radius r), by Hopkins's OTF. "
        "Held by tests/psf/test_diffraction.py (tabulated value + 0.005).",
    )
    return rows


def colour_table(img: np.ndarray) -> None:
    rows = []
    R = OPENINGS["F9.85"]
    for name, lam in zip("RGB", CHANNEL_WAVELENGTHS_NM):
        one = fraunhofer_kernel(DiscPupil(R), DiffractionScale(lam, 0.00645, D)).kernel
        n = one.shape[0]
        band = np.zeros_like(one)
        for w in np.linspace(lam - 50, lam + 50, 11):
            otf = pupil_otf(DiscPupil(R), DiffractionScale(w, 0.00645, D))
            band += kernel_from_otf(otf, size=n, max_lost=0.01).kernel / 11
        rows.append(
            {
                "channel": name,
                "wavelength nm": lam,
                "kernel L1 to its +-50 nm band": float(np.abs(one - band).sum()),
                "image RMS to its band": rms(blur(img, one), blur(img, band)),
                "diffraction RMS": rms(blur(img, band), img),
            }
        )
    record(
        "Diffraction: one wavelength per channel against the channel's band (issue 36)",
        rows,
        "F9.85. Band: 11 equally weighted wavelengths over +-50 nm around the channel's (a "
        "sensor channel spans ~100 nm); skimage's camera, 512x512, white = 1.",
    )


Q, N, SLOPE, X0 = 8, 256, 1 / 16, 100.0


def slanted_bar() -> np.ndarray:
    """A periodic bright bar, its left edge at x = X0 + y SLOPE px, 8x finer than the pixels."""
    ss = 4
    c = (np.arange(N * Q * ss) + 0.5) / (Q * ss) - 0.5
    u = np.mod(c[None, :] - X0 - c[:, None] * SLOPE, N)
    return ((u > 0) & (u < N / 2)).astype(float).reshape(N * Q, ss, N * Q, ss).mean(axis=(1, 3))


def dead_leaves(seed: int = 0) -> np.ndarray:
    """Periodic dead leaves of rectangles (grey levels uniform, sides ~ 1/x^3 from 2 to 64 px),
    8x finer than the pixels: every scale of edge, as a sharpness test chart has."""
    rng = np.random.default_rng(seed)
    n = N * Q
    img = np.full((n, n), 0.5)
    for _ in range(4000):
        h, w = (Q * 2 / np.sqrt(1 - rng.uniform(0, 1 - (2 / 64) ** 2, 2))).astype(int)
        y, x = rng.integers(0, n, 2)
        img[np.ix_(np.arange(y, y + h) % n, np.arange(x, x + w) % n)] = rng.uniform()
    return img


def postprocess_table() -> None:
    cam_R = OPENINGS["F9.85"]
    scale = DiffractionScale(549.0, 0.00645, D)
    otf = disc_otf(DiscPupil(cam_R), scale)
    kernels = {
        s: fraunhofer_kernel(DiscPupil(cam_R), scale, sampling=s).kernel for s in ("band", "pixel")
    }
    big = np.random.default_rng(1).uniform(0, 1, (1024, 1024))
    per_mp = {s: min(timed(lambda k=k: diffract_image(big, k))[1] for _ in range(3))
              for s, k in kernels.items()}  # fmt: skip
    inner = (slice(80, -80), slice(80, -80))
    rows = []
    for scene_name, fine in (("slanted edge", slanted_bar()), ("dead leaves", dead_leaves())):
        for r in (0.0, 2.0):

            def geo_t(nx, ny, r=r):
                return pillbox_otf(np.hypot(ny[:, None], nx[None, :]), r)

            def ex_t(nx, ny, r=r):
                return otf.grid(nx, ny) * geo_t(nx, ny)

            geo = supersampled_capture(fine, Q, geo_t if r else None, nyquist_tol=1e-2)
            exact = supersampled_capture(fine, Q, ex_t)
            rows.append(
                {
                    "scene": scene_name,
                    "r px": r,
                    "method": "none (geometric only)",
                    "RMS to reference": rms(geo[inner], exact[inner]),
                    "s per MP per channel": 0.0,
                }
            )
            for s, k in kernels.items():
                post = diffract_image(geo, k)
                rows.append(
                    {
                        "scene": scene_name,
                        "r px": r,
                        "method": f"post-process, {s} kernel",
                        "RMS to reference": rms(post[inner], exact[inner]),
                        "s per MP per channel": per_mp[s],
                    }
                )
    nu = np.linspace(0.05, 0.45, 17)
    fine = slanted_bar()
    geo, exact = supersampled_capture(fine, Q), supersampled_capture(fine, Q, otf.grid)
    want = circular_mtf(nu, scale.lambda_n_px(cam_R))
    angle = np.degrees(np.arctan(SLOPE))
    base = edge_mtf(geo, angle, X0, nu)
    dev = {"reference (diffraction before the pixel)": exact}
    dev.update({f"post-process, {s} kernel": diffract_image(geo, k) for s, k in kernels.items()})
    notes = "; ".join(
        f"{name}: {np.max(np.abs(edge_mtf(img, angle, X0, nu) / base - want)):.4f}"
        for name, img in dev.items()
    )
    record(
        "Diffraction as a capture post-process: error against a reference 8x finer (issue 36)",
        rows,
        "Normal mode's F9.85 disc, green (549 nm), 6.45 um pixels. Reference: the scene on a "
        "grid 8x finer, imaged through the OTF (x the pillbox's transfer at r = 2) before "
        "pixel integration (pacam_render.wave.supersampled). Post-process: the geometric "
        "capture convolved with the kernel of max_lost 0.002 (band: 347 px, its |k| decays "
        "slowly from the band edge; pixel: 153 px). RMS over the 256x256 "
        "capture less an 80 px border, white = 1. Must-show, in-focus edge: max |MTF ratio "
        f"(with / without) - circular MTF| over 0.05-0.45 cycles/px: {notes}.",
    )


def box_once_table() -> None:
    from pacam_render.model.modes import capture_camera
    from pacam_render.psf.analytic import design_psf
    from pacam_render.psf.diffraction import diffracted_kernel, supersample

    rows = []
    for mode in ("coded", "flutter", "normal"):
        cam = capture_camera(prototype(), mode)
        shape = design_psf(cam, mode, 0.4).shape

        def build(c, f, fine, mode=mode):
            return design_psf(c, mode, 0.4 * f, fine)

        for wl in CHANNEL_WAVELENGTHS_NM:
            ref = diffracted_kernel(build, cam, mode, wl, shape, factor=21)
            best = supersample(cam, mode, wl)
            for f in sorted({3, 5, 7, 9, 11, 15, best}):
                k, sec = timed(partial(diffracted_kernel, build, cam, mode, wl, shape, factor=f))
                rows.append(
                    {
                        "mode": mode,
                        "nm": wl,
                        "kernel px": shape[0],
                        "fine grid": f"{f}x" + (" (default)" if f == best else ""),
                        "L1 vs 21x": float(np.abs(k - ref).sum()),
                        "seconds": sec,
                    }
                )
    record(
        "Box-once diffraction kernels: fine grid against error and run time (issue 36)",
        rows,
        "the prototype's capture cameras (F9.85 openings), 0.4 px/ms, geometric kernel's own "
        "size; the Airy core (6 px) on the fine grid, the rings on the coarse one. The error "
        "falls as the fine pixel squared; the default (supersample) takes fine pixels of at "
        "most lambda N / 7. Held by tests/psf/test_diffraction.py (default < 1e-3 L1).",
    )


TABLES = {
    "kernels": lambda a: kernel_table(image(), a.quick),
    "stiff": lambda a: stiff_table(),
    "combination": lambda a: combination_table(),
    "colour": lambda a: colour_table(image()),
    "postprocess": lambda a: postprocess_table(),
    "box_once": lambda a: box_once_table(),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer max_lost values")
    ap.add_argument("--only", choices=sorted(TABLES), help="one table (default: all)")
    args = ap.parse_args()
    for name, table in TABLES.items():
        if args.only in (None, name):
            table(args)


if __name__ == "__main__":
    main()
