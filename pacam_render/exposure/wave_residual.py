"""What a capture's diffraction in the rays leaves out, as an RMS on the capture (issue 45,
item 3).

A path-traced capture's camera rays cannot know the depth they will meet, so they diffract as
the geometric disc convolved with the Airy pattern (:mod:`pacam_render.render.ray_diffraction`);
the exact paraxial PSF of the defocused opening (:mod:`pacam_render.psf.exact_defocus`)
differs where W020 is of the order of a wave (L1 0.25 at the prototype's r = 2 px). The
capture's record sizes that difference on the capture itself: the RMS over the window of
(K_exact - K_rays) * sharp, each the capture camera's static kernel at s = 0 at the channel's
wavelength, times the capture's light factor (capture units). Measured on the ``sharp`` layer
(the scene at t = 0): still objects exactly, moving ones as if held. Without the truth layers
it is not measured.
"""

from __future__ import annotations

import numpy as np

PAD_PX = 16
"""Added to each side of the geometric kernel for the Airy pattern's and the exact PSF's
rings (98 % of the in-focus Airy pattern's light at F9.85)."""


def residual_kernels(cam, mode: str, n_channels: int, pitch_mm: float) -> list | None:
    """Per channel, K_exact - K_rays (sums to 0); None where the exact kernel does not apply
    (bitmaps, a pinhole, or beyond the exact table's defocus)."""
    from ..model.modes import mode as mode_of
    from ..psf.analytic import design_psf
    from ..psf.diffraction import diffracted_kernel
    from ..psf.exact_defocus import exact_defocus_kernel, mode_edge_phase
    from ..render.ray_defocus import PSI_MAX
    from ..wave.patterns import channel_wavelengths_nm, shows_bitmaps

    if mode_of(mode).schedule is None or shows_bitmaps(cam, mode):
        return None
    waves = channel_wavelengths_nm(n_channels)
    if any(mode_edge_phase(cam, mode, wl, pitch_mm)[0] > PSI_MAX for wl in waves):
        return None
    h, w = design_psf(cam, mode, 0.0, None, origin="pinhole").shape
    shape = (h + 2 * PAD_PX, w + 2 * PAD_PX)

    def build(c, f, fine):
        return design_psf(c, mode, 0.0, fine, origin="pinhole")

    out = []
    for wl in waves:
        rays = diffracted_kernel(build, cam, mode, wl, shape, pitch_mm)
        exact = exact_defocus_kernel(cam, mode, 0.0, "pinhole", wl, shape, pitch_mm)
        out.append(exact - rays)
    return out


def residual_rms(sharp, cam, mode: str, pitch_mm: float, light_factor: float) -> float | None:
    """RMS over the window (its kernel-wide border left out) of (K_exact - K_rays) * sharp, in
    the capture's units; None when not measured (module docstring)."""
    from scipy.signal import fftconvolve

    if sharp is None:
        return None
    sharp = np.asarray(sharp, float)
    planes = [sharp] if sharp.ndim == 2 else [sharp[..., c] for c in range(sharp.shape[2])]
    kernels = residual_kernels(cam, mode, len(planes), pitch_mm)
    if kernels is None:
        return None
    b = kernels[0].shape[0] // 2
    diffs = [fftconvolve(p, k, mode="same")[b:-b, b:-b] for p, k in zip(planes, kernels)]
    if not diffs[0].size:
        return None
    return float(np.sqrt(np.mean([np.mean(d * d) for d in diffs]))) * light_factor
