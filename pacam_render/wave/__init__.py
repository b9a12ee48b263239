"""Wave optics of the programmable aperture: pupils, their Fraunhofer diffraction on the
sensor's pixels, and defocus with diffraction (issue 36, item 1).

A numpy-only leaf between :mod:`pacam_render.model` (the camera, its LCoS bitmaps) and
:mod:`pacam_render.psf` (the analytic kernels, which gain the diffraction factor through
:mod:`pacam_render.psf.diffraction`). One concept per module:

- :mod:`.scale`: the F-number scale of diffraction, N = F_min R_max / R: the pupil in mm on
  the LCoS lies D = 2 F_min R_max from the image (``../shared/PHYSICS.md``).
- :mod:`.pupil`: ideal discs and pupils of square cells (LCoS bitmaps exactly).
- :mod:`.otf`: the pupil's autocorrelation, the transfer function of |FT(pupil)|^2.
- :mod:`.fraunhofer`: the pixel-integrated kernel, summed exactly from the OTF, with its
  truncation and aliasing stated (:class:`DiffractionKernel`).
- :mod:`.reference`: the closed forms it is checked against (Airy pattern, circular MTF, J1).
- :mod:`.defocus`: the exact PSF of a defocused disc (Hopkins) and the geometric combination.
- :mod:`.patterns`: the kernel of a capture mode: its openings, weighted by light, per colour
  channel (Rec. 709 primaries' dominant wavelengths: 611, 549, 464 nm).
- :mod:`.image`: diffraction as a post-process of rendered captures (per channel, per
  pattern window), with the ``band`` kernel.
- :mod:`.supersampled` (a reference capture with diffraction before the pixel, 8x finer) and
  :mod:`.edge_mtf` (a slanted edge's MTF): what the post-process is measured with.

Error against run time: ``benchmarks/bench_diffraction.py`` and ``benchmarks/RESULTS.md``.
"""

from .defocus import defocus_kernel, w020_mm
from .fraunhofer import DEFAULT_MAX_LOST, DiffractionKernel, fraunhofer_kernel
from .image import diffract_capture, diffract_image
from .patterns import (
    CHANNEL_WAVELENGTHS_NM,
    GREY_WAVELENGTH_NM,
    mode_diffraction_kernel,
    pattern_kernels,
)
from .pupil import DiscPupil, GridPupil, disc_pupil, mask_pupil
from .reference import airy_psf, circular_mtf
from .scale import DiffractionScale, scale_for

__all__ = [
    "CHANNEL_WAVELENGTHS_NM",
    "DEFAULT_MAX_LOST",
    "GREY_WAVELENGTH_NM",
    "DiffractionKernel",
    "DiffractionScale",
    "DiscPupil",
    "GridPupil",
    "airy_psf",
    "circular_mtf",
    "defocus_kernel",
    "diffract_capture",
    "diffract_image",
    "disc_pupil",
    "fraunhofer_kernel",
    "mask_pupil",
    "mode_diffraction_kernel",
    "pattern_kernels",
    "scale_for",
    "w020_mm",
]
