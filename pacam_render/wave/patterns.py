"""The diffraction kernel of a capture: the openings its mode shows, each one's Fraunhofer
PSF, weighted by the light it passes.

Which openings a mode shows follows :data:`pacam_render.model.modes.MODES` (as
:func:`~pacam_render.model.modes.sensor_params` does): a bitmap schedule in a mode that shows
its patterns (``coded``) shows each LCoS pattern for one window; every other mode shows discs
of the camera's radius R (the parabola, a designed schedule's centres, still modes, Levin's
and the fluttered shutter), which all diffract alike wherever they sit (shift theorem), so
one Airy kernel serves the whole exposure. The ``reference`` is a pinhole: no aperture.

For a bitmap schedule the kernel is sum_k w_k d_k / sum_k w_k, with d_k pattern k's Fraunhofer
kernel and w_k its open area (sum of tau) times its window (all windows are equal). That is
exact for a still point. For a moving one it puts every pattern's diffraction on the whole
path: exact when the patterns have the same shape (a rasterised parabola of discs), an
approximation otherwise.

Colour. The renderer's channels are Rec. 709 (sRGB) primaries, so each channel is diffracted
at its primary's dominant wavelength (CIE 1931 2 deg, D65 white, computed with
colour-science's ``dominant_wavelength``): R 611 nm, G 549 nm, B 464 nm. Grey captures use
550 nm. A channel is in truth a band (a sensor channel spans ~100 nm), whose PSF is the
average of Airy patterns scaled with lambda; one wavelength per channel leaves out that
smoothing of the rings (measured in ``benchmarks/bench_diffraction.py``).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..model.modes import mode as mode_of
from .fraunhofer import DEFAULT_MAX_LOST, DiffractionKernel, fraunhofer_kernel, kernel_from_otf
from .otf import mixture_otf, pupil_cutoff
from .pupil import DiscPupil, mask_pupil
from .scale import scale_for

CHANNEL_WAVELENGTHS_NM = (611.0, 549.0, 464.0)
"""R, G, B: the dominant wavelengths of the Rec. 709 primaries (module docstring), nm."""
GREY_WAVELENGTH_NM = 550.0
"""The wavelength of a grey (single-channel) capture, nm."""


def shows_bitmaps(cam, mode: str) -> bool:
    """The capture shows the LCoS patterns of a bitmap schedule (as ``sensor_params``)."""
    m = mode_of(mode)
    return cam.pattern_masks is not None and m.schedule == "parabolic" and not m.continuous


def mode_pupils(cam, mode: str) -> list[tuple[object, float]]:
    """The openings a ``mode`` capture by camera ``cam`` shows, and their weights.

    Parameters
    ----------
    cam : CameraDesign
        The camera that takes the capture
        (:func:`~pacam_render.model.modes.capture_camera`'s result).
    mode : str
        A capture mode with an aperture (not ``reference``).

    Returns
    -------
    list of (pupil, weight)
        One :class:`~pacam_render.wave.pupil.DiscPupil` of radius R with weight 1, or one
        :class:`~pacam_render.wave.pupil.GridPupil` per open pattern of a bitmap schedule,
        weighted by its open area x window (mm^2 x window); black patterns pass no light and
        are left out.
    """
    m = mode_of(mode)
    if m.schedule is None:
        raise ParameterError(
            f"mode {mode!r} is a pinhole (the sharp reference): it has no aperture to diffract"
        )
    if not shows_bitmaps(cam, mode):
        return [(DiscPupil(cam.R_mm), 1.0)]
    stack = cam.pattern_masks
    return list(stack.once("pupils", lambda: _stack_pupils(stack)))


def _stack_pupils(stack) -> tuple:
    """Each open pattern's pupil and light (kept on the stack: every wavelength asks)."""
    out = []
    for mask in stack.array:
        area = float(mask.sum(dtype=np.float64)) * stack.pitch_mm**2
        if area > 0.0:
            out.append((mask_pupil(mask, stack.pitch_mm), area))
    return tuple(out)


def _distinct(parts: list) -> list:
    """The pupils with their weights summed over identical openings (shifted copies of one
    opening diffract alike, and their crops are equal)."""
    out: dict = {}
    for pupil, weight in parts:
        a = getattr(pupil, "amplitude", None)
        key = (a.shape, a.tobytes()) if a is not None else pupil
        out[key] = (pupil, out[key][1] + weight) if key in out else (pupil, weight)
    return list(out.values())


def _distinct_pupils(cam, mode: str) -> list:
    """:func:`_distinct` of :func:`mode_pupils`, kept on a bitmap stack."""
    if not shows_bitmaps(cam, mode):
        return _distinct(mode_pupils(cam, mode))
    return list(
        cam.pattern_masks.once("distinct_pupils", lambda: tuple(_distinct(mode_pupils(cam, mode))))
    )


def mode_diffraction_kernel(
    cam,
    mode: str,
    wavelength_nm: float,
    size: int | None = None,
    max_lost: float = DEFAULT_MAX_LOST,
    sampling: str = "pixel",
    pixel_pitch_mm: float | None = None,
) -> DiffractionKernel:
    """The diffraction kernel of a ``mode`` capture by ``cam`` at one wavelength.

    Parameters
    ----------
    cam : CameraDesign
        The camera that takes the capture (as for ``design_psf``).
    mode : str
        A mode of :data:`~pacam_render.model.modes.MODES` other than ``reference``.
    wavelength_nm : float
        nm, in [300, 1100]; :data:`CHANNEL_WAVELENGTHS_NM` per colour channel.
    size, max_lost, sampling
        As for :func:`~pacam_render.wave.fraunhofer.fraunhofer_kernel` (of the whole mixture).
    pixel_pitch_mm : float, optional
        As for :func:`~pacam_render.wave.scale.scale_for`.

    Returns
    -------
    DiffractionKernel
        The patterns' kernels' mean, weighted by their light: the kernel of the mean of their
        OTFs (:func:`~pacam_render.wave.otf.mixture_otf`), with its own ``lost`` and ``alias``.

    Examples
    --------
    >>> from pacam_render.model.camera import prototype
    >>> d = mode_diffraction_kernel(prototype(), "coded", 549.0)
    >>> d.kernel.shape, round(float(d.kernel.sum()), 12)
    ((153, 153), 1.0)
    """
    scale = scale_for(cam, wavelength_nm, pixel_pitch_mm)
    parts = _distinct_pupils(cam, mode)
    if len(parts) == 1:
        return fraunhofer_kernel(parts[0][0], scale, size, max_lost, sampling)
    # the patterns' light-weighted mean, from the mean of their OTFs: one kernel, exact
    return kernel_from_otf(mixture_otf(parts, scale), size, max_lost, sampling)


def mode_cutoff(cam, mode: str, wavelength_nm: float, pixel_pitch_mm=None) -> float:
    """The highest image frequency (cycles/px) any opening of a ``mode`` capture passes:
    p / (lambda N) for a disc of F-number N (Goodman 6-31). Arguments as for
    :func:`mode_diffraction_kernel`."""
    scale = scale_for(cam, wavelength_nm, pixel_pitch_mm)
    return max(pupil_cutoff(pupil, scale) for pupil, _ in mode_pupils(cam, mode))


def pattern_kernels(
    cam,
    mode: str,
    wavelength_nm: float,
    max_lost: float = DEFAULT_MAX_LOST,
    sampling: str = "band",
    pixel_pitch_mm: float | None = None,
) -> list[DiffractionKernel | None]:
    """One kernel per window of the exposure, for convolving rendered images (:mod:`.image`).

    A bitmap schedule in a mode that shows it: one kernel per pattern, in the schedule's order
    (None for a black pattern, whose window passes no light); identical openings share one.
    Any other mode: a list of one kernel, for the whole exposure (every disc diffracts alike).

    Parameters
    ----------
    cam, mode, wavelength_nm, max_lost, pixel_pitch_mm
        As for :func:`mode_diffraction_kernel`.
    sampling : {"band", "pixel"}
        ``"band"`` (default here): the kernel for images whose pixels already integrate
        (:mod:`.image`).

    Returns
    -------
    list of DiffractionKernel or None
    """
    scale = scale_for(cam, wavelength_nm, pixel_pitch_mm)
    if not shows_bitmaps(cam, mode):
        ((pupil, _),) = mode_pupils(cam, mode)
        return [fraunhofer_kernel(pupil, scale, None, max_lost, sampling)]
    out, cache = [], {}
    stack = cam.pattern_masks
    for mask in stack.array:
        if not np.any(mask > 0):
            out.append(None)
            continue
        pupil = mask_pupil(mask, stack.pitch_mm)
        key = (pupil.amplitude.shape, pupil.amplitude.tobytes())
        if key not in cache:
            cache[key] = fraunhofer_kernel(pupil, scale, None, max_lost, sampling)
        out.append(cache[key])
    return out


def channel_wavelengths_nm(n_channels: int) -> tuple[float, ...]:
    """The wavelength of each channel of an image: R, G, B (:data:`CHANNEL_WAVELENGTHS_NM`)
    for 3 channels, :data:`GREY_WAVELENGTH_NM` for 1."""
    if n_channels == 3:
        return CHANNEL_WAVELENGTHS_NM
    if n_channels == 1:
        return (GREY_WAVELENGTH_NM,)
    raise ParameterError(f"n_channels must be 1 (grey) or 3 (RGB), got {n_channels!r}")
