"""Pupils: what the aperture lets through, as a field in the LCoS plane.

Two kinds, both in mm on the LCoS and in the orientation of
:mod:`pacam_render.model.masks` (rows grow downwards, columns to the image's right):

- :class:`DiscPupil`: an ideal disc of radius R (the openings of parabolic and designed
  schedules, and every still mode). Its diffraction is the Airy pattern, in closed form.
- :class:`GridPupil`: a complex amplitude on square cells of side ``pitch_mm``, each cell
  uniform. An LCoS bitmap is exactly this (one cell per display pixel), so its Fraunhofer
  pattern is exact; a disc or a phase sampled this way is an approximation whose error falls
  as the cells shrink (:func:`disc_pupil`).

A bitmap's grey level tau is an *intensity* transmittance, so its amplitude is sqrt(tau) (an
analogue modulator). A binary ferroelectric LCoS that makes grey by dithering in time would
instead average the PSFs of its binary sub-frames; that is not modelled. Only |FT|^2 is used,
which no shift of the opening changes (Goodman, Introduction to Fourier Optics, 3rd ed.,
Sec. 2.1.5, the shift theorem), so a :class:`GridPupil` keeps only its open cells' bounding
box.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_positive

MAX_PUPIL_CELLS = 2**24
"""Most cells a sampled pupil may have (16.8 M: a 4096 x 4096 grid, ~256 MB complex)."""


@dataclass(frozen=True)
class DiscPupil:
    """An ideal disc opening of radius ``radius_mm`` on the LCoS (anywhere: |FT|^2 does not
    depend on where)."""

    radius_mm: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "radius_mm", check_positive("radius_mm", self.radius_mm, "mm"))

    @property
    def energy_mm2(self) -> float:
        """Integral of |P|^2, mm^2: the open area."""
        return float(np.pi * self.radius_mm**2)

    @property
    def edge_mm(self) -> float:
        """Length of the pupil's edge, mm (sets the 1/r tail of its PSF)."""
        return float(2.0 * np.pi * self.radius_mm)


@dataclass(frozen=True, eq=False)
class GridPupil:
    """A pupil of uniform square cells: ``amplitude[i, j]`` on the cell of side ``pitch_mm``
    at row i (downwards) and column j (to the image's right).

    Build one with :func:`mask_pupil` or :func:`disc_pupil`; the amplitude is cropped to the
    bounding box of its non-zero cells.
    """

    amplitude: np.ndarray
    pitch_mm: float

    def __post_init__(self) -> None:
        a = np.asarray(self.amplitude)
        if a.ndim != 2 or a.size == 0:
            raise ParameterError(f"amplitude must be a non-empty 2-D array, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ParameterError("amplitude must be finite (found NaN or inf)")
        a = _crop(a.astype(np.complex128 if np.iscomplexobj(a) else np.float64))
        a.setflags(write=False)
        object.__setattr__(self, "amplitude", a)
        object.__setattr__(self, "pitch_mm", check_positive("pitch_mm", self.pitch_mm, "mm"))

    @property
    def energy_mm2(self) -> float:
        """Integral of |P|^2, mm^2 (Parseval: the PSF's total energy in these units)."""
        return float(np.sum(np.abs(self.amplitude) ** 2) * self.pitch_mm**2)

    @property
    def edge_mm(self) -> float:
        """sum over cell edges of |a1 - a2|^2 times the edge's length, mm: for a binary pupil
        its (staircase) perimeter. It sets the 1/r tail of the PSF."""
        a = np.pad(self.amplitude, 1)
        jumps = np.sum(np.abs(np.diff(a, axis=0)) ** 2) + np.sum(np.abs(np.diff(a, axis=1)) ** 2)
        return float(jumps * self.pitch_mm)

    @property
    def extent_mm(self) -> tuple[float, float]:
        """Height and width of the open bounding box, mm."""
        h, w = self.amplitude.shape
        return h * self.pitch_mm, w * self.pitch_mm


def _crop(a: np.ndarray) -> np.ndarray:
    """The bounding box of the non-zero cells; ParameterError if there are none."""
    rows = np.flatnonzero(np.any(a != 0, axis=1))
    if rows.size == 0:
        raise ParameterError(
            "pupil: the pattern is closed (transmittance 0 everywhere): no light passes, so "
            "it has no diffraction pattern"
        )
    cols = np.flatnonzero(np.any(a[rows[0] : rows[-1] + 1] != 0, axis=0))
    return np.ascontiguousarray(a[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1])


def mask_pupil(mask, pitch_mm: float, subdivide: int = 1) -> GridPupil:
    """The pupil of one LCoS bitmap: amplitude sqrt(tau) on each display pixel.

    Parameters
    ----------
    mask : array_like
        ``(H, W)`` intensity transmittance in [0, 1], in :mod:`pacam_render.model.masks`'s
        orientation.
    pitch_mm : float
        The display's pixel pitch, mm.
    subdivide : int
        Split each display pixel into ``subdivide`` x ``subdivide`` equal cells. The pupil is
        the same (exactly), only its sampling is finer; kept for checks.

    Returns
    -------
    GridPupil

    Raises
    ------
    ParameterError
        If the mask is closed (all black), not 2-D, or outside [0, 1].
    """
    tau = np.asarray(mask, dtype=float)
    if tau.ndim != 2:
        raise ParameterError(f"mask must be one (H, W) pattern, got shape {tau.shape}")
    if tau.size and not np.all(np.isfinite(tau)):
        raise ParameterError("mask: transmittance must be finite (found NaN or inf)")
    if tau.size and (tau.min() < 0.0 or tau.max() > 1.0):
        raise ParameterError(
            f"mask: transmittance must be in [0, 1], got [{tau.min():g}, {tau.max():g}]"
        )
    s = int(subdivide)
    if s < 1 or s != subdivide:
        raise ParameterError(f"subdivide must be an integer >= 1, got {subdivide!r}")
    amp = _crop(np.sqrt(tau))
    if amp.size * s * s > MAX_PUPIL_CELLS:
        raise ParameterError(
            f"subdivide = {s} gives {amp.size * s * s} pupil cells, more than "
            f"{MAX_PUPIL_CELLS}; use a smaller subdivide"
        )
    if s > 1:
        amp = np.kron(amp, np.ones((s, s)))
    return GridPupil(amp, check_positive("pitch_mm", pitch_mm, "mm") / s)


def disc_pupil(
    radius_mm: float, samples_per_radius: int = 64, supersample: int = 8, phase=None
) -> GridPupil:
    """A disc of radius R sampled on square cells of side R / ``samples_per_radius``.

    Each cell's amplitude is the fraction of it inside the disc (``supersample`` x
    ``supersample`` points per cell), times exp(i phase(rho)) at the cell's centre if
    ``phase`` is given (a function of rho = r / R, e.g. defocus, :mod:`.defocus`).

    The cells are an approximation of the disc and of a smooth phase; the error of the
    Fraunhofer kernel against the closed-form Airy pattern falls as the cells shrink (measured
    in ``tests/wave/test_fraunhofer.py``: L1 ~ 1e-3 at 64 samples per radius).
    """
    R = check_positive("radius_mm", radius_mm, "mm")
    n = int(samples_per_radius)
    s = int(supersample)
    if n < 2 or n != samples_per_radius:
        raise ParameterError(
            f"samples_per_radius must be an integer >= 2, got {samples_per_radius!r}"
        )
    if s < 1 or s != supersample:
        raise ParameterError(f"supersample must be an integer >= 1, got {supersample!r}")
    if (2 * n) ** 2 > MAX_PUPIL_CELLS:
        raise ParameterError(
            f"samples_per_radius = {n} gives {(2 * n) ** 2} cells, more than {MAX_PUPIL_CELLS}"
        )
    c = (np.arange(2 * n) + 0.5 - n) / n  # cell centres in units of R
    sub = (np.arange(2 * n * s) + 0.5 - n * s) / (n * s)
    inside = (sub[:, None] ** 2 + sub[None, :] ** 2) <= 1.0
    amp = inside.reshape(2 * n, s, 2 * n, s).mean(axis=(1, 3)).astype(complex)
    if phase is not None:
        rho = np.hypot(c[:, None], c[None, :])
        amp = amp * np.exp(1j * np.asarray(phase(rho), dtype=float))
    else:
        amp = amp.real
    return GridPupil(amp, R / n)
