"""The diffraction factor of the analytic model: any kernel convolved with the diffraction
kernel of the capture's openings (:mod:`pacam_render.wave`).

The analytic model (Eq. 14) is geometric: a point images to pillboxes of radius r = |beta| R
along its path. Diffraction at the opening adds the Fraunhofer PSF of each pattern, so the
kernel becomes the geometric one convolved with
:func:`~pacam_render.wave.patterns.mode_diffraction_kernel` (one Airy kernel for disc
schedules, the patterns' kernels weighted by open area x time for bitmaps).

This is the combination "geometric defocus convolved with Fraunhofer diffraction", and it is
an approximation: against the exact Fourier-optics PSF of a defocused disc it is off by an L1
of 0.09-0.50 for r = 0.5-4 px at F9.85 (``benchmarks/RESULTS.md``, "Defocus + diffraction",
and ``tests/psf/test_diffraction.py``), exact at r = 0. Both factors are pixel-integrated,
the package's kernel convention, which makes the combination exact for an in-focus point at a
pixel's centre. A kernel meant to deconvolve captures that were diffracted as a post-process
(:mod:`pacam_render.wave.image`, ``band`` kernels) should use ``sampling="band"`` here too:
the pixel-integrated factor applies the pixel's box twice (an extra sinc(nu) in the transfer
function, 0.70 at 0.45 cycles/px), the band factor has the optics' transfer function exactly
on the pixel grid's band.

Opt-in: :func:`~pacam_render.psf.analytic.design_psf` applies it only with ``diffraction_nm``.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from ..wave.fraunhofer import DEFAULT_MAX_LOST, MAX_KERNEL_PX
from ..wave.patterns import mode_cutoff, mode_diffraction_kernel
from .grid import kernel_shape, normalise


def convolve_kernels(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The full 2-D convolution of two odd, centred kernels: odd, centred, sum a x sum b.

    Examples
    --------
    >>> k = convolve_kernels(np.ones((3, 3)) / 9, np.ones((1, 5)) / 5)
    >>> k.shape, round(float(k.sum()), 12), round(float(k[1, 3]), 4)
    ((3, 7), 1.0, 0.0667)
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    shape = (a.shape[0] + b.shape[0] - 1, a.shape[1] + b.shape[1] - 1)
    if a.size * b.size <= 2**22:  # small: the direct sum is exact and fast enough
        out = np.zeros(shape)
        for (i, j), v in np.ndenumerate(b if b.size <= a.size else a):
            if v != 0.0:
                other = a if b.size <= a.size else b
                out[i : i + other.shape[0], j : j + other.shape[1]] += v * other
        return out
    fa = np.fft.rfft2(a, shape)
    fb = np.fft.rfft2(b, shape)
    out = np.fft.irfft2(fa * fb, shape)
    if a.min() >= 0.0 and b.min() >= 0.0:  # FFT round-off (~1e-19) of either sign where both
        np.maximum(out, 0.0, out=out)  # are dark: PSFs stay non-negative, as deconvolve checks
    return out


def crop_centred(kernel: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The centred ``shape`` window of an odd kernel (zero-padded where it is larger)."""
    h, w = shape
    H, W = kernel.shape
    out = np.zeros((h, w))
    ci, cj, oi, oj = H // 2, W // 2, h // 2, w // 2
    r = min(oi, ci), min(h - oi, H - ci)
    c = min(oj, cj), min(w - oj, W - cj)
    out[oi - r[0] : oi + r[1], oj - c[0] : oj + c[1]] = kernel[
        ci - r[0] : ci + r[1], cj - c[0] : cj + c[1]
    ]
    return out


def with_diffraction(
    kernel: np.ndarray,
    cam,
    mode: str,
    wavelength_nm: float,
    size=None,
    max_lost: float = DEFAULT_MAX_LOST,
    sampling: str = "pixel",
    pixel_pitch_mm: float | None = None,
) -> np.ndarray:
    """``kernel`` convolved with the diffraction kernel of a ``mode`` capture by ``cam``.

    Both kernels are pixel-integrated, so the pixel's box enters twice: exact for a point in
    focus (a delta kernel), an L1 gap of up to 0.017 (coded) and 0.075 (flutter) for blurred
    kernels. :func:`diffracted_kernel` counts the box once, as the rays do; the analytic
    kernels of captures use it.

    Parameters
    ----------
    kernel : numpy.ndarray
        An odd, centred, normalised kernel (e.g. :func:`~pacam_render.psf.analytic.design_psf`).
    cam : CameraDesign
        The camera that takes the capture (as for ``design_psf``).
    mode : str
        The capture mode (not ``reference``).
    wavelength_nm : float
        nm, in [300, 1100]: one colour channel's
        (:data:`~pacam_render.wave.patterns.CHANNEL_WAVELENGTHS_NM`) or 550 for grey.
    size : int or (int, int), optional
        Odd output size; default the full convolution (the kernel's size plus the
        diffraction kernel's, less one). A smaller size crops, renormalises and warns
        (``PSFTruncationWarning``) with the light it leaves out.
    max_lost, sampling
        As for :func:`~pacam_render.wave.fraunhofer.fraunhofer_kernel`.
    pixel_pitch_mm : float, optional
        The image's pixel pitch, mm: a binned capture's (``capture.json`` records it in
        ``optics_error.diffraction``); default the design's native pitch.

    Returns
    -------
    numpy.ndarray
        Odd, centred, summing to 1.

    Examples
    --------
    The prototype's coded kernel at rest, in green:

    >>> from pacam_render.model.camera import prototype
    >>> from pacam_render.psf.analytic import design_psf
    >>> cam = prototype()
    >>> k = with_diffraction(design_psf(cam, "coded"), cam, "coded", 549.0)
    >>> k.shape, round(float(k.sum()), 12)
    ((177, 177), 1.0)
    """
    d = mode_diffraction_kernel(
        cam, mode, wavelength_nm, None, max_lost, sampling, pixel_pitch_mm=pixel_pitch_mm
    )
    out = convolve_kernels(kernel, d.kernel)
    if size is None:
        return out / out.sum()
    shape = kernel_shape(size, 0.0, 0.0, 0.0)
    return normalise(crop_centred(out, shape), float(out.sum()))


DECONVOLUTION_MAX_LOST = 0.01
"""The Airy light a capture's deconvolution kernel leaves out (renormalised): the far rings,
a haze over ~150 px at F9.85, would otherwise make the kernel larger than the images a study
deblurs; 1 % leaves a 31 px diffraction kernel at F9.85."""


def full_shape(
    shape, cam, mode: str, wavelength_nm: float, pixel_pitch_mm=None, max_lost=DEFAULT_MAX_LOST
) -> tuple:
    """The shape of a kernel of ``shape`` convolved with the mode's diffraction kernel that
    leaves out ``max_lost`` of the light (what :func:`with_diffraction` returns without
    ``size``)."""
    d = mode_diffraction_kernel(cam, mode, wavelength_nm, None, max_lost, "pixel", pixel_pitch_mm)
    return (int(shape[0]) + d.kernel.shape[0] - 1, int(shape[1]) + d.kernel.shape[1] - 1)


SUPERSAMPLE = (3, 15)
"""The fewest and the most pixels per side that :func:`diffracted_kernel` splits each pixel
into (odd: the fine grid's centre pixel is the coarse one's centre)."""

NEAR_PX = 6
"""Half-width (px) of the Airy pattern's core that :func:`diffracted_kernel` samples on the
fine grid; the rings beyond it are smooth over a pixel and are applied on the coarse one."""


def supersample(cam, mode: str, wavelength_nm: float, pixel_pitch_mm=None) -> int:
    """The fine pixels per side :func:`diffracted_kernel` uses: the smallest odd factor with
    fine pixels of at most lambda N / 7 (7 x the openings' cut-off frequency, cycles/px),
    within :data:`SUPERSAMPLE`.

    The fine grid places the geometric kernel's light at each fine pixel's centre, an error
    that falls as the square of the fine pixel over lambda N, and is largest where the
    geometric kernel has sharp edges. Against the same kernel on 21x finer pixels, at F9.85
    and 0.4 px/ms (549 nm): L1 0.009 (fluttered shutter, in focus) and 0.004 (coded, r = 2
    px) with 3x finer pixels, 0.0008 and 0.0004 with 9x. A fixed 3 put the fluttered
    shutter's rendered PSF 6 Monte Carlo floors from its model
    (``tests/psf_render/test_psf_render.py``)."""
    need = 7.0 * mode_cutoff(cam, mode, wavelength_nm, pixel_pitch_mm)
    f = max(SUPERSAMPLE[0], min(SUPERSAMPLE[1], math.ceil(need)))
    return f + 1 - f % 2


def diffracted_kernel(
    build,
    cam,
    mode: str,
    wavelength_nm: float,
    shape: tuple[int, int],
    pixel_pitch_mm: float | None = None,
    max_lost: float | None = None,
    factor: int | None = None,
) -> np.ndarray:
    """A pixel-integrated kernel with the opening's diffraction, as the rays make it: the
    continuous geometric PSF convolved with the Airy pattern, then integrated over each pixel.

    :func:`with_diffraction` convolves an already pixel-integrated kernel with a
    pixel-integrated Airy kernel, so the pixel's box enters twice (an L1 gap of 0.017 to a
    rendered coded PSF at r = 2 px, 5x its Monte Carlo floor). Here the geometric kernel is
    built on pixels ``factor`` times finer (``build``, the camera with its pixels split) and
    convolved with the Airy pattern's core (:data:`NEAR_PX`) integrated over those fine pixels,
    then binned back: the box enters once. The fine grid holds each fine pixel's light at its
    centre, an error that falls as the square of the fine pixel (:func:`supersample`). The
    rings beyond the core vary slowly over a pixel and are applied to the binned kernel.

    Parameters
    ----------
    build : callable
        ``build(cam, factor, fine_shape)``: the geometric kernel of ``cam`` (px quantities,
        speeds included, ``factor`` times the coarse ones) in the odd ``fine_shape``.
    cam : CameraDesign
    mode : str
    wavelength_nm : float
    shape : (int, int)
        The coarse geometric kernel's odd shape.
    pixel_pitch_mm : float, optional
        The coarse pixels' pitch (a binned capture's); default ``cam.pixel_pitch_mm``.
    max_lost : float, optional
        None: the result keeps ``shape``. A fraction: ``shape`` grows by the diffraction
        kernel that leaves out this much of the light (:func:`full_shape`; the rings beyond
        are left out and the window renormalised).
    factor : int, optional
        Odd; default :func:`supersample`'s.

    Returns
    -------
    numpy.ndarray
        ``shape``, non-negative, summing to 1 (the window's light, renormalised).
    """
    pitch = float(pixel_pitch_mm or cam.pixel_pitch_mm)
    if max_lost is not None:
        shape = full_shape(shape, cam, mode, wavelength_nm, pitch, max_lost)
    h, w = int(shape[0]), int(shape[1])
    if factor is not None and (int(factor) != factor or factor < 1 or factor % 2 == 0):
        raise ParameterError(f"factor must be an odd integer >= 1, got {factor!r}")
    f = int(factor or supersample(cam, mode, wavelength_nm, pitch))
    fine = cam.with_(
        width_px=f * cam.width_px,
        height_px=f * cam.height_px,
        pixel_pitch_mm=cam.pixel_pitch_mm / f,
    )
    kf = np.asarray(build(fine, f, (f * h, f * w)), float)
    n = 2 * NEAR_PX + 1
    # the core cut from a kernel 3x its size: the periodic sum's wrapped tails (``alias``)
    # fall ~9x, to L1 4e-5 against the Airy kernel in focus, where they flattened its peak 5e-4
    core = mode_diffraction_kernel(fine, mode, wavelength_nm, 3 * f * n, 0.5, "pixel", pitch / f)
    near = convolve_kernels(kf, crop_centred(core.kernel * (1.0 - core.lost), (f * n, f * n)))
    near = crop_centred(near, (f * h, f * w)).reshape(h, f, w, f).sum(axis=(1, 3))
    # the rings beyond the core: the coarse Airy kernel with the core's block taken out, on
    # the coarse geometric kernel (offsets up to max(h, w) - 1 reach the window)
    size = min(max(n, 2 * max(h, w) - 1), MAX_KERNEL_PX)
    d = mode_diffraction_kernel(cam, mode, wavelength_nm, size, 0.5, "pixel", pitch)
    far = d.kernel * (1.0 - d.lost)
    c, r = size // 2, NEAR_PX
    far[c - r : c + r + 1, c - r : c + r + 1] = 0.0
    k = kf.reshape(h, f, w, f).sum(axis=(1, 3))
    coarse = near + crop_centred(convolve_kernels(k, far), (h, w))
    return coarse / coarse.sum()
