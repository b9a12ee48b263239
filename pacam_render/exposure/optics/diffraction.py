"""Diffraction on a rendered capture: ``diffraction`` = ``on``, ``off`` or ``auto`` (issue 36).

The rays trace geometric optics through the opening; the opening's Fraunhofer diffraction is
added after the render, channel by channel, as a convolution of the rendered image with the
``band`` kernel of :mod:`pacam_render.wave.fraunhofer` (whose transfer function on the pixel
grid is the OTF itself, so the pixel's own integration is not counted twice). That is the
geometric image convolved with Fraunhofer diffraction: defocus and occlusion stay exactly
those of the rays, and its error against the exact Fourier-optics PSF of a defocused disc is
:func:`pacam_render.psf.combination.combination_error` (tabulated in ``benchmarks/RESULTS.md``).
Each colour channel is diffracted at its primary's dominant wavelength
(:data:`~pacam_render.wave.patterns.CHANNEL_WAVELENGTHS_NM`), a grey capture at 550 nm.

Why a post-process and not a jitter of each ray's film position: every disc schedule diffracts
alike wherever its opening sits (shift theorem), so one convolution of the whole exposure is
the per-ray jitter's expectation, without its added variance; it costs one FFT per channel
(``benchmarks/bench_diffraction.py``). A bitmap schedule's patterns diffract differently: with
per-pattern windows (``per_pattern``) each window gets its own kernel; without, the
light-weighted mean kernel (:func:`~pacam_render.wave.patterns.mode_diffraction_kernel`),
exact for points in focus and stated so in the record.

The Monte Carlo variance goes through the same convolution with the squared kernel (pixels'
errors are independent), so ``mc_sigma`` stays the error of the image written. ``auto``
measures the effect, RMS over the window of (diffracted - geometric) with the Monte Carlo
noise's share removed (E|n - k*n|^2 = var * (delta - k)^2), and includes diffraction unless it
is below the capture's noise target (without a target: below its own Monte Carlo sigma, the
smallest change the capture can show).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ParameterError
from ...render.samplers import quantum
from ...wave.fraunhofer import DEFAULT_MAX_LOST
from ...wave.image import diffract_image
from ...wave.patterns import (
    channel_wavelengths_nm,
    mode_diffraction_kernel,
    pattern_kernels,
    shows_bitmaps,
)

DIFFRACTION_CHOICES = ("auto", "on", "off")
"""The ``diffraction`` settings of a capture."""
PREVIEW_SPP = 32
"""Samples per pixel of ``auto``'s geometric preview (the capture's sampler) of the scene frozen
at t = 0 (:func:`~pacam_render.exposure.direct.preview_scene`), in renders of the capture's own
per-step samples (:func:`~pacam_render.exposure.direct.preview_plan`)."""


def preview_sampling(sampler: str, steps: list) -> tuple[int, int]:
    """(samples per render, passes) of ``auto``'s preview: about :data:`PREVIEW_SPP` samples,
    in renders of the capture's own per-step samples (``steps``, one of its passes' time steps;
    at most half the preview's). A sampler's convergence depends on the samples of one render:
    a pass split into many time steps of 4 spp converges as 4 spp renders do, not as one
    render of their sum (a moving capture stated up to 1.5x the sigma that a preview of whole
    passes predicted), so each preview pass is one such render, and its sigma scales to the
    capture's samples."""
    q = quantum(sampler)
    per_step = sorted(s.spp for s in steps)[len(steps) // 2]
    n = max(q, min(per_step, PREVIEW_SPP // 2) // q * q)
    return n, max(2, PREVIEW_SPP // n)


def check_diffraction(value) -> str:
    """``value`` if it is one of :data:`DIFFRACTION_CHOICES`, else ParameterError."""
    if value not in DIFFRACTION_CHOICES:
        raise ParameterError(
            f"diffraction must be one of {', '.join(DIFFRACTION_CHOICES)}, got {value!r}"
        )
    return value


@dataclass
class Diffracted:
    """A capture's image, pattern windows and variance after diffraction, and its record."""

    image: np.ndarray
    patterns: dict
    variance: np.ndarray
    record: dict


_KERNELS: dict = {}
"""The last few :func:`channel_kernels` results, by what they depend on (a 381 px kernel takes
about a second per wavelength: a study's or a light-field store's many captures of one opening
compute it once)."""
_KEPT = 8


def _kernel_key(cam, mode: str, n_channels: int, pitch_mm: float, per_window: bool) -> tuple:
    """What the kernels depend on: the openings (a disc's radius, or the bitmaps' digest), the
    lens (F_min and R_max set D) and the sampling; not the focus or the openings' centres."""
    bitmaps = shows_bitmaps(cam, mode)
    opening = ("bitmap", cam.pattern_masks.digest) if bitmaps else ("disc", float(cam.R_mm))
    lens = (float(cam.F_min), float(cam.R_max_mm))
    return (*opening, *lens, int(n_channels), float(pitch_mm), bool(per_window and bitmaps))


def channel_kernels(cam, mode: str, n_channels: int, pitch_mm: float, per_window: bool):
    """Per channel, the ``band`` kernels: one per pattern window when ``per_window`` (a bitmap
    schedule's, None for a black pattern), else a list of one for the whole exposure. The
    kernels are shared with earlier calls of the same openings (read-only)."""
    key = _kernel_key(cam, mode, n_channels, pitch_mm, per_window)
    if key not in _KERNELS:
        if len(_KERNELS) >= _KEPT:
            _KERNELS.pop(next(iter(_KERNELS)))
        _KERNELS[key] = _channel_kernels(cam, mode, n_channels, pitch_mm, per_window)
    return _KERNELS[key]


def kernels_built(cam, mode: str, n_channels: int, pitch_mm: float, per_window: bool) -> bool:
    """Whether :func:`channel_kernels` has these kernels already (they cost nothing now)."""
    return _kernel_key(cam, mode, n_channels, pitch_mm, per_window) in _KERNELS


def _channel_kernels(cam, mode: str, n_channels: int, pitch_mm: float, per_window: bool):
    out = []
    for wl in channel_wavelengths_nm(n_channels):
        if per_window or not shows_bitmaps(cam, mode):
            out.append(pattern_kernels(cam, mode, wl, DEFAULT_MAX_LOST, "band", pitch_mm))
        else:
            d = mode_diffraction_kernel(cam, mode, wl, None, DEFAULT_MAX_LOST, "band", pitch_mm)
            out.append([d])
    return out


def _planes(a: np.ndarray) -> int:
    return 1 if a.ndim == 2 else a.shape[2]


def _diffract(image: np.ndarray, kernels: list, k: int, square: bool = False) -> np.ndarray:
    ks = [c[k].kernel ** 2 if square else c[k].kernel for c in kernels]
    return diffract_image(image, ks if _planes(image) > 1 else ks[0])


def _residual_kernels(kernels: list) -> list:
    """(delta - k)^2 of each channel's whole-exposure kernel: how much MC noise the
    difference (diffracted - geometric) holds, per unit variance."""
    out = []
    for c in kernels:
        k = -np.asarray(c[0].kernel, float)
        k[k.shape[0] // 2, k.shape[1] // 2] += 1.0
        out.append(k * k)
    return out


def effect_rms(image, diffracted, variance, kernels) -> float:
    """RMS over the window of (diffracted - image), its Monte Carlo share removed."""
    d2 = float(np.mean((np.asarray(diffracted) - np.asarray(image)) ** 2))
    res = _residual_kernels(kernels)
    noise = diffract_image(variance, res if _planes(variance) > 1 else res[0])
    return float(np.sqrt(max(d2 - float(np.mean(noise)), 0.0)))


def diffract(image, patterns: dict, variance, cam, mode: str, pitch_mm: float) -> Diffracted:
    """The capture with its openings' diffraction (module docstring), its variance through
    the squared kernels, and the record: how, at which wavelengths, the kernels' errors."""
    img = np.asarray(image, float)
    n = _planes(img)
    per_window = shows_bitmaps(cam, mode) and bool(patterns)
    kernels = channel_kernels(cam, mode, n, pitch_mm, per_window)
    if per_window:
        out = np.zeros_like(img)
        new_patterns = {}
        for k, window in patterns.items():
            if kernels[0][k] is None:
                new_patterns[k] = np.zeros_like(window)
                continue
            new_patterns[k] = _diffract(np.asarray(window, float), kernels, k)
            out += new_patterns[k]
        whole = channel_kernels(cam, mode, n, pitch_mm, False)  # for the variance
    else:
        out, new_patterns, whole = _diffract(img, kernels, 0), {}, kernels
    var = np.maximum(_diffract(np.asarray(variance, float), whole, 0, square=True), 0.0)
    rec = {
        "how": "post-process: each channel convolved with its opening's Fraunhofer band kernel"
        + (", per pattern window" if per_window else ""),
        "wavelengths_nm": list(channel_wavelengths_nm(n)),
        "pixel_pitch_mm": pitch_mm,
        "kernel_px": int(whole[0][0].kernel.shape[0]),
        "kernel_lost": float(max(c[0].lost for c in whole)),
        "kernel_alias": float(max(c[0].alias for c in whole)),
    }
    if shows_bitmaps(cam, mode) and not per_window:
        rec["approximation"] = (
            "a static bitmap capture is diffracted with the light-weighted mean of its "
            "patterns' kernels: exact in focus; render per_pattern for one kernel per pattern"
        )
    rec["effect_rms"] = effect_rms(img, out, variance, whole)
    return Diffracted(out, new_patterns, var, rec)


def diffract_model(image, cam, mode: str, pitch_mm: float) -> np.ndarray:
    """A model image of a capture (geometric optics) with the diffraction a capture adds:
    each channel convolved with its whole-exposure band kernel, as :func:`diffract` does, so
    that a model and a diffracted capture compare like with like."""
    img = np.asarray(image, float)
    return _diffract(img, channel_kernels(cam, mode, _planes(img), pitch_mm, False), 0)


def decide(setting: str, effect: float, threshold: float, why: str) -> tuple[bool, str]:
    """Whether ``auto`` (or ``on`` / ``off``) includes diffraction, and the reason in words."""
    check_diffraction(setting)
    if setting != "auto":
        return setting == "on", f"{setting}, as asked"
    keep = effect >= threshold
    verb = "included" if keep else "left out"
    rel = ">=" if keep else "<"
    return keep, f"auto: {verb}, its effect {effect:.3g} {rel} {why} {threshold:.3g}"
