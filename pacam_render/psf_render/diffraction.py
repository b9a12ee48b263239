"""Ray-traced PSFs with the opening's diffraction, and the model they are compared with (issue
36, item 6: rendered and analytic PSFs like with like).

The rays diffract as a capture's do (:mod:`pacam_render.render.ray_diffraction`): each
particle lands a draw from the disc opening's Airy pattern away, per colour channel of the
variant. The PSF film is one luminance channel, so a colour variant's rendered kernel is the
luminance-weighted mixture of the three channels' kernels, each the geometric kernel convolved
with its own Airy pattern (:func:`~pacam_render.psf.diffraction.with_diffraction`); a mono
variant's is the 550 nm one. The pixel's box enters once, as in the rays
(:func:`~pacam_render.psf.diffraction.diffracted_kernel`). The model is cropped to the rendered
window and renormalised, as the rendered kernel is (light that the far rings carry past the
window is in neither).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..model.camera import CameraDesign
from ..model.modes import mode as mode_of
from ..psf.diffraction import diffracted_kernel
from ..psf.exact_defocus import exact_defocus_kernel, mode_edge_phase
from ..render.ray_defocus import PSI_MAX
from ..render.ray_diffraction import sensor_properties
from ..render.variant import is_mono
from ..wave.patterns import channel_wavelengths_nm, shows_bitmaps

LUMINANCE_RGB = (0.212671, 0.715160, 0.072169)
"""The weights of linear sRGB's R, G and B in luminance: what Mitsuba's ``luminance`` film
stores of an RGB variant's radiance."""


def channels(variant: str) -> int:
    """Colour channels of a Mitsuba variant: 1 for a mono one (:func:`~..render.variant.
    is_mono`), else 3."""

    return 1 if is_mono(variant) else 3


def sensor_params(design: CameraDesign, mode: str, n_channels: int, pitch_mm=None) -> dict:
    """The ``programmable_aperture`` parameters that put diffraction in the rays of a PSF
    render on pixels of ``pitch_mm`` (default the design's own); refused for a pinhole mode or
    a bitmap schedule."""

    if mode_of(mode).schedule is None:
        raise ParameterError(f"diffraction: mode {mode!r} is a pinhole, it has no opening")
    if shows_bitmaps(design, mode):
        raise ParameterError(
            "diffraction: a PSF render diffracts disc openings in the rays; a bitmap schedule's "
            "kernel is diffracted analytically: leave out `render`"
        )
    waves = channel_wavelengths_nm(n_channels)
    return sensor_properties(design, waves, pitch_mm or design.pixel_pitch_mm)


def diffracted_model(
    build,
    design: CameraDesign,
    mode: str,
    shape,
    n_channels: int,
    pitch_mm=None,
    speed: float = 0.0,
    origin: str = "t0",
) -> np.ndarray:
    """The kernel the rays make with diffraction: per channel the geometric kernel (``build``,
    as :func:`~pacam_render.psf.diffraction.diffracted_kernel` takes it) convolved with its
    Airy pattern on pixels of ``pitch_mm`` (default the design's own), the box counted once,
    cropped to ``shape`` and renormalised; then mixed by luminance."""

    weights = LUMINANCE_RGB if n_channels == 3 else (1.0,)
    waves = channel_wavelengths_nm(n_channels)
    pitch = pitch_mm or design.pixel_pitch_mm
    exact = all(mode_edge_phase(design, mode, wl, pitch)[0] <= PSI_MAX for wl in waves)
    out = np.zeros(tuple(shape))
    for w, wl in zip(weights, waves):
        if exact:  # the particles' exact defocused PSF (:mod:`..render.defocus_draw`)
            out += w * exact_defocus_kernel(design, mode, speed, origin, wl, shape, pitch)
        else:
            out += w * diffracted_kernel(build, design, mode, wl, shape, pitch_mm)
    return out / out.sum()
