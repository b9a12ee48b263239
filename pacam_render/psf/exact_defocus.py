"""The analytic kernel with the exact paraxial defocus of the opening (issue 45, item 2): every
pattern's disc replaced by the defocused disc's Fourier-optics PSF.

Each pattern's PSF is |FT{P exp(i 2 pi W020 rho^2 / lambda)}|^2 at the pattern's geometric
place (its chief ray through the opening's centre, the parallax beta c), and the patterns add
incoherently over time (``../shared/PHYSICS.md``, "Defocus with diffraction"). Every disc
pattern of one capture has the same radius and depth, so the kernel is the point's
trajectory (its patterns' places and its motion, :func:`~.analytic.design_trajectory`) with
one exact PSF, E(rho) of :func:`~pacam_render.psf.defocused_disc.radial_density` at
psi = pi r / (2 lambda N), in place of the disc at every point of it. E is integrated over
each pixel once (a table of offsets :data:`STEP_PX` apart, read bilinearly at the
trajectory's exact sub-pixel places: a fine pixel grid would move every place to its fine
pixel's centre, 0.014 L1 at 5 fine pixels per pixel), taken over the whole window and
renormalised with it, as a rendered kernel is.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from ..model.modes import capture_camera
from .analytic import design_trajectory
from .defocused_disc import PSI_MAX, radial_density
from .diffraction import diffracted_kernel, full_shape
from .trajectory import bin_statistics, extent

STEP_PX = 0.05
"""Spacing of the pixel-integrated PSF's table and of the trajectory's bins, px (E's finest
feature, lambda N, is 0.84 px at F9.85)."""


def edge_phase(cam, r_px: float, wavelength_nm: float, pixel_pitch_mm: float):
    """(psi, lambda N px) of ``cam``'s opening blurred to r px."""
    lam_n_px = wavelength_nm * 1e-6 * cam.F_number / pixel_pitch_mm
    return 0.5 * math.pi * r_px / lam_n_px, lam_n_px


def mode_edge_phase(design, mode: str, wavelength_nm: float, pixel_pitch_mm: float):
    """:func:`edge_phase` of a ``mode`` capture's camera at its object depth."""

    cam = capture_camera(design, mode)
    return edge_phase(cam, cam.r_px, wavelength_nm, pixel_pitch_mm)


def pixel_integrated(psi: float, lam_n_px: float, half_px: float) -> tuple[np.ndarray, np.ndarray]:
    """G(dx, dy) = the light of E centred at 0 in the pixel centred at (dx, dy), on a grid of
    :data:`STEP_PX` over [-half_px, half_px]^2; and the grid's axis (px)."""

    m = int(round(1.0 / STEP_PX))  # samples per pixel
    n = 2 * int(math.ceil((half_px + 1.0) / STEP_PX)) + 1
    x = (np.arange(n) - n // 2) * STEP_PX
    radii = np.arange(0.0, math.sqrt(2.0) * x[-1] + 2 * STEP_PX, 0.1 * STEP_PX)
    e = np.interp(np.hypot(x[:, None], x[None, :]), radii, radial_density(radii, psi, lam_n_px))
    e *= STEP_PX**2
    # a pixel's box: m samples, the two at its edges half-weighted (trapezoid), each axis
    box = np.ones(m + 1)
    box[0] = box[-1] = 0.5
    from scipy.ndimage import convolve1d

    g = convolve1d(convolve1d(e, box, axis=0, mode="constant"), box, axis=1, mode="constant")
    keep = slice(m, n - m)
    return g[keep, keep], x[keep]


def exact_defocus_kernel(design, mode: str, s: float, origin: str, wavelength_nm: float,
                         shape, pixel_pitch_mm=None) -> np.ndarray:  # fmt: skip
    """The pixel-integrated kernel of a ``mode`` capture with every disc pattern's exact
    defocused PSF (module docstring): the point's trajectory (:func:`~.analytic.
    design_trajectory`), binned along x every :data:`STEP_PX`, each bin's mass deposited with
    E integrated over each pixel.

    Parameters
    ----------
    design : CameraDesign
    mode : str
    s : float
        The point's speed, px/ms.
    origin : str
        ``t0`` or ``pinhole`` (:func:`~.analytic.design_psf`).
    wavelength_nm : float
    shape : (int, int)
        The odd kernel shape.
    pixel_pitch_mm : float, optional
        The pixels' pitch; default the design's.

    Returns
    -------
    numpy.ndarray
        ``shape``, non-negative, summing to 1 (the window's light, renormalised).
    """
    from scipy.ndimage import map_coordinates

    if design.pattern_masks is not None:
        raise ParameterError("the exact defocused kernel needs disc openings, not bitmaps")
    pitch = float(pixel_pitch_mm or design.pixel_pitch_mm)
    segments, r = design_trajectory(design, mode, s, origin)
    psi, lam_n_px = edge_phase(_capture_camera(design, mode), r, wavelength_nm, pitch)
    h, w = int(shape[0]), int(shape[1])
    g, axis = pixel_integrated(psi, lam_n_px, max(h, w))
    xc = np.arange(w) - w // 2  # pixel centres
    yc = np.arange(h) - h // 2
    kernel = np.zeros((h, w))
    lo, hi = extent(segments)
    edges = np.arange(lo - STEP_PX, hi + 2 * STEP_PX, STEP_PX)
    for y in sorted({seg.y for seg in segments}):
        mass, moment = bin_statistics([seg for seg in segments if seg.y == y], edges)
        for m, c in zip(mass[mass > 0], moment[mass > 0] / mass[mass > 0]):
            dx, dy = np.meshgrid(xc - c, yc - y)
            at = [(dy - axis[0]) / STEP_PX, (dx - axis[0]) / STEP_PX]
            kernel += m * map_coordinates(g, at, order=1, mode="constant")
    kernel = np.clip(kernel, 0.0, None)
    return kernel / kernel.sum()


def _capture_camera(design, mode: str):

    return capture_camera(design, mode)


def ray_kernel(build, design, mode: str, s: float, origin: str, wavelength_nm: float, shape,
               pixel_pitch_mm=None, max_lost=None, psf: str = "exact") -> np.ndarray:  # fmt: skip
    """The kernel with the opening's diffraction as the rays make it (issue 45, item 2).

    ``psf`` ``exact``: the exact defocused PSF (:func:`exact_defocus_kernel`), as disc
    openings' rays draw it (:mod:`pacam_render.render.kernels.defocus_draw`), where the opening's
    defocus is within the rays' table (:data:`~pacam_render.render.ray_defocus.PSI_MAX`);
    beyond it, or with ``psf`` ``fraunhofer`` (a leaky LCoS's or a pixel grid's rays, an older
    capture, a bitmap), the geometric kernel convolved with the Airy pattern, the pixel's box
    once (:func:`~.diffraction.diffracted_kernel`, which ``build`` and ``max_lost`` are for).
    With ``max_lost``, the exact kernel takes the shape that leaves out that share of the Airy
    pattern's light (:func:`~.diffraction.full_shape`).
    """

    pitch = float(pixel_pitch_mm or design.pixel_pitch_mm)
    exact = (psf == "exact" and design.pattern_masks is None
             and mode_edge_phase(design, mode, wavelength_nm, pitch)[0] <= PSI_MAX)  # fmt: skip
    if not exact:
        return diffracted_kernel(build, design, mode, wavelength_nm, shape, pixel_pitch_mm,
                                 max_lost)  # fmt: skip
    if max_lost is not None:
        shape = full_shape(shape, design, mode, wavelength_nm, pitch, max_lost)
    return exact_defocus_kernel(design, mode, s, origin, wavelength_nm, shape, pitch)
