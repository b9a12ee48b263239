"""What a capture's diffraction in the rays leaves out, as an RMS on the capture (issue 45,
item 3).

Two cases, each measured on the ``sharp`` layer (the scene at t = 0: still objects exactly,
moving ones as if held) with the capture camera's static kernels at s = 0 at each channel's
wavelength, times the capture's light factor (capture units); without the truth layers it is
not measured.

- **Rays with the Airy draw** (a leaky LCoS or a pixel grid:
:mod:`pacam_render.exposure.optics.budget`) diffract
  as the geometric disc convolved with the Airy pattern
  (:mod:`pacam_render.render.ray_diffraction`), while the exact paraxial PSF of the defocused
  opening (:mod:`pacam_render.psf.exact_defocus`) differs where W020 is of the order of a wave
  (L1 0.25 at the prototype's r = 2 px): :func:`residual_rms` is the RMS over the window of
  (K_exact - K_rays) * sharp.
- **Rays with the exact PSF** (disc openings otherwise,
:mod:`pacam_render.render.kernels.defocus_draw`)
  are exact over surfaces at one depth; at an occluding edge no ray method is exact (the
  occluder cuts the beam of the points behind it, and their PSF is then a part-blocked
  pupil's, while a ray draws the whole opening's). :func:`occlusion_rms` sizes what is left
  there by its scale, the whole wave effect (K_exact - K_geometric) * sharp on the pixels
  within the kernel's reach of a depth jump in the ``depth`` layer (and nothing elsewhere):
  not a strict bound, the order of what an edge can change.
"""

from __future__ import annotations

import numpy as np

from ...model.modes import mode as mode_of
from ...psf.analytic import design_psf
from ...psf.diffraction import diffracted_kernel
from ...psf.exact_defocus import exact_defocus_kernel, mode_edge_phase
from ...render.ray_defocus import PSI_MAX
from ...wave.patterns import channel_wavelengths_nm, shows_bitmaps

PAD_PX = 16
"""Added to each side of the geometric kernel for the Airy pattern's and the exact PSF's
rings (98 % of the in-focus Airy pattern's light at F9.85)."""


def residual_kernels(
    cam, mode: str, n_channels: int, pitch_mm: float, against: str = "rays"
) -> list | None:
    """Per channel, K_exact - K_rays (``against`` rays: the geometric disc with the Airy
    pattern) or K_exact - K_geometric (``geometric``), each summing to 0; None where the exact
    kernel does not apply (bitmaps, a pinhole, or beyond the exact table's defocus)."""

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
    geometric = None
    if against == "geometric":
        g = design_psf(cam, mode, 0.0, None, origin="pinhole")
        geometric = np.pad(g / g.sum(), PAD_PX)
    for wl in waves:
        rays = (
            geometric
            if geometric is not None
            else diffracted_kernel(build, cam, mode, wl, shape, pitch_mm)
        )
        exact = exact_defocus_kernel(cam, mode, 0.0, "pinhole", wl, shape, pitch_mm)
        out.append(exact - rays)
    return out


def residual_rms(sharp, cam, mode: str, pitch_mm: float, light_factor: float) -> float | None:
    """RMS over the window (its kernel-wide border left out) of (K_exact - K_rays) * sharp, in
    the capture's units; None when not measured (module docstring)."""
    return _rms(sharp, None, cam, mode, pitch_mm, light_factor, "rays")


def occlusion_rms(
    sharp, depth, cam, mode: str, pitch_mm: float, light_factor: float
) -> float | None:
    """The scale of what exact-PSF rays leave out at occluding edges: the RMS over the window
    (its kernel-wide border left out) of (K_exact - K_geometric) * sharp on the pixels within
    the kernel's reach of a depth jump, 0 elsewhere; None when not measured."""
    if depth is None:
        return None
    return _rms(sharp, np.asarray(depth, float), cam, mode, pitch_mm, light_factor, "geometric")


def depth_jumps(depth: np.ndarray, reach_px: int) -> np.ndarray:
    """Pixels within ``reach_px`` of a depth jump: neighbours more than 1 % apart in depth, or
    a surface next to none (depth 0)."""
    from scipy.ndimage import binary_dilation, maximum_filter, minimum_filter

    hi, lo = maximum_filter(depth, 3), minimum_filter(depth, 3)
    jump = (hi - lo) > 0.01 * np.maximum(hi, 1e-12)
    return binary_dilation(jump, iterations=reach_px) if jump.any() else jump


def _rms(sharp, depth, cam, mode, pitch_mm, light_factor, against) -> float | None:
    from scipy.signal import fftconvolve

    if sharp is None:
        return None
    sharp = np.asarray(sharp, float)
    planes = [sharp] if sharp.ndim == 2 else [sharp[..., c] for c in range(sharp.shape[2])]
    kernels = residual_kernels(cam, mode, len(planes), pitch_mm, against)
    if kernels is None:
        return None
    b = kernels[0].shape[0] // 2
    diffs = [fftconvolve(p, k, mode="same")[b:-b, b:-b] for p, k in zip(planes, kernels)]
    if not diffs[0].size:
        return None
    if depth is not None:  # the occluding edges' band only
        band = depth_jumps(depth, b)[b:-b, b:-b]
        diffs = [d * band for d in diffs]
    return float(np.sqrt(np.mean([np.mean(d * d) for d in diffs]))) * light_factor
