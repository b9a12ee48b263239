"""Diffraction as a post-process of rendered images: each channel convolved with its kernel.

A rendered pixel already integrates the geometric image over its area, so the kernel that
adds diffraction to it is not the pixel-integrated PSF (that would integrate twice, an extra
sinc(nu) in the transfer function: 0.70 at 0.45 cycles/px) but the ``band`` kernel
(:mod:`.fraunhofer`), whose transfer function on the pixel grid is exactly the OTF H(nu) for
|nu| <= 1/2. What it cannot do is put back what the pixel grid never held: the geometric
image's content above Nyquist (aliased) is diffracted as if it were at its alias, and a point
that images inside one pixel spreads as the band-limited Airy pattern, not the
pixel-integrated one. ``benchmarks/bench_diffraction.py`` measures the error of both kernels
against a reference rendered 8x finer (diffraction before the pixel), per second.

Convolution is by FFT with the image mirrored at its borders (``numpy.pad(mode="reflect")``):
within a kernel's half-width of the border the mirrored scene stands in for the unseen one.

A bitmap schedule's patterns diffract differently: convolve each pattern window's image with
its own kernel (:func:`~pacam_render.wave.patterns.pattern_kernels`) before summing the
windows; disc schedules need one kernel for the whole exposure (shift theorem).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..limits import check_memory
from .fraunhofer import DEFAULT_MAX_LOST
from .otf import fast_len as _fast
from .patterns import channel_wavelengths_nm, pattern_kernels, shows_bitmaps


def convolve_same(channel: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """One 2-D channel convolved with an odd, centred kernel, same size, mirrored borders."""
    kh, kw = kernel.shape
    if kh % 2 == 0 or kw % 2 == 0:
        raise ParameterError(f"kernel must have odd sides, got {kernel.shape}")
    h, w = channel.shape
    ph, pw = kh // 2, kw // 2
    mode = "reflect" if ph < h and pw < w else "symmetric"
    padded = np.pad(channel, ((ph, ph), (pw, pw)), mode=mode)
    shape = (_fast(padded.shape[0] + kh - 1), _fast(padded.shape[1] + kw - 1))
    check_memory(f"a {shape[0]}x{shape[1]} FFT convolution", 24.0 * shape[0] * shape[1], "size")
    f = np.fft.rfft2(padded, shape) * np.fft.rfft2(kernel, shape)
    full = np.fft.irfft2(f, shape)
    return full[2 * ph : 2 * ph + h, 2 * pw : 2 * pw + w]


def diffract_image(image, kernels) -> np.ndarray:
    """A rendered image with diffraction added: each channel convolved with its kernel.

    Parameters
    ----------
    image : array_like
        ``(H, W)`` or ``(H, W, C)`` linear values.
    kernels : array_like or sequence of array_like
        One odd, centred kernel for every channel, or one per channel (C of them): e.g.
        ``band`` kernels of :func:`~pacam_render.wave.patterns.mode_diffraction_kernel` at
        :data:`~pacam_render.wave.patterns.CHANNEL_WAVELENGTHS_NM`.

    Returns
    -------
    numpy.ndarray
        float64, the image's shape. A kernel that sums to 1 keeps the image's mean (up to its
        borders).

    Examples
    --------
    >>> img = np.zeros((9, 9)); img[4, 4] = 1.0
    >>> out = diffract_image(img, np.full((3, 3), 1 / 9))
    >>> out.shape, round(float(out.sum()), 12), round(float(out[3, 3]), 4)
    ((9, 9), 1.0, 0.1111)
    """
    img = np.asarray(image, dtype=float)
    if img.ndim not in (2, 3) or img.size == 0:
        raise ParameterError(f"image must be (H, W) or (H, W, C), got shape {img.shape}")
    planes = img[..., None] if img.ndim == 2 else img
    c = planes.shape[2]
    ks = [np.asarray(k, float) for k in kernels] if _is_sequence(kernels) else None
    if ks is None:
        ks = [np.asarray(kernels, float)] * c
    if len(ks) != c:
        raise ParameterError(f"kernels: one per channel ({c}) or one for all, got {len(ks)}")
    out = np.stack([convolve_same(planes[..., i], ks[i]) for i in range(c)], axis=-1)
    return out[..., 0] if img.ndim == 2 else out


def _is_sequence(kernels) -> bool:
    return isinstance(kernels, (list, tuple)) or (
        isinstance(kernels, np.ndarray) and kernels.ndim == 3
    )


def diffract_capture(
    image, cam, mode: str, window_images=None, max_lost: float = DEFAULT_MAX_LOST
) -> np.ndarray:
    """A rendered capture with the diffraction of its openings, per colour channel (opt-in).

    Parameters
    ----------
    image : array_like
        ``(H, W, 3)`` RGB or ``(H, W)`` / ``(H, W, 1)`` grey capture, linear; channels are
        diffracted at :func:`~pacam_render.wave.patterns.channel_wavelengths_nm`.
    cam : CameraDesign
        The camera that took it (:func:`~pacam_render.model.modes.capture_camera`).
    mode : str
        Its capture mode (not ``reference``).
    window_images : sequence of array_like, optional
        A bitmap schedule's capture split by pattern window (they sum to ``image``): each is
        convolved with its pattern's kernel. Required for bitmap schedules, unused otherwise.
    max_lost : float
        As for :func:`~pacam_render.wave.fraunhofer.fraunhofer_kernel`.

    Returns
    -------
    numpy.ndarray
        The diffracted capture, ``image``'s shape.
    """
    img = np.asarray(image, dtype=float)
    n = 1 if img.ndim == 2 else img.shape[2]
    waves = channel_wavelengths_nm(n)
    per_channel = [pattern_kernels(cam, mode, w, max_lost, "band") for w in waves]
    if not shows_bitmaps(cam, mode):
        return diffract_image(img, [ks[0].kernel for ks in per_channel])
    if window_images is None or len(window_images) != len(per_channel[0]):
        raise ParameterError(
            f"window_images: a bitmap schedule diffracts per pattern; pass its "
            f"{len(per_channel[0])} pattern windows' images (they sum to the capture)"
        )
    out = np.zeros_like(img)
    for k, window in enumerate(window_images):
        if per_channel[0][k] is None:  # a black pattern passes no light
            continue
        out += diffract_image(window, [ks[k].kernel for ks in per_channel])
    return out
