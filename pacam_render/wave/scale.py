"""The scale of diffraction: the pupil in mm on the LCoS, the image in sensor pixels.

The ray geometry runs on a scaled thin lens (``Z_p`` = 9.72 mm from the field of view and
6.45 um pixels, the LCoS itself as the stop: F0.70 at the full disc), while diffraction must
use the real camera's F-number (``../shared/PHYSICS.md``, "Wave optics and radiometry"): a disc
of radius R is at

    N = F_min R_max / R                                              (paper's scale)

so F2.8 at the full 512-px LCoS disc and F9.85 at the 145.5-px opening. Both statements are
one geometry: the pupil, measured in mm on the LCoS, lies a distance

    D = 2 F_min R_max                                                 (= 39.0 mm)

from the image, so that N = D / (2R) for every disc, and any bitmap is scaled the same way.
Fraunhofer diffraction (Goodman, *Introduction to Fourier Optics*, 3rd ed., Eq. 4-17 and
Sec. 6.3) then maps a pupil lag l (mm) to the image frequency nu = l / (lambda D) (cycles/mm),
so in sensor pixels of pitch p

    nu_px = l p / (lambda D)   [cycles/px],       lambda N / p   [px]  for a disc.

At 550 nm and 6.45 um: lambda N / p = 0.840 px at F9.85, the Airy pattern's first zero is
1.22 lambda N = 1.02 px, and its cut-off frequency p / (lambda N) is 1.19 cycles/px.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ParameterError, check_positive, check_range

MIN_WAVELENGTH_NM = 300.0
"""Shortest wavelength accepted, nm (a silicon sensor's range starts near 300-400 nm)."""
MAX_WAVELENGTH_NM = 1100.0
"""Longest wavelength accepted, nm (silicon's band gap)."""

AIRY_FIRST_ZERO = 1.2196698912665045
"""The first zero of the Airy pattern in units of lambda N: j_{1,1} / pi (Born & Wolf 8.5.2)."""


def check_wavelength(wavelength_nm: float) -> float:
    """``wavelength_nm`` as float if it is in [300, 1100] nm, else ParameterError."""
    return check_range("wavelength_nm", wavelength_nm, MIN_WAVELENGTH_NM, MAX_WAVELENGTH_NM, "nm")


@dataclass(frozen=True)
class DiffractionScale:
    """How a pupil in mm maps to an image in sensor pixels at one wavelength.

    Parameters
    ----------
    wavelength_nm : float
        Vacuum wavelength, nm, in [300, 1100].
    pixel_pitch_mm : float
        The sensor's pixel pitch, mm (6.45 um for the ICX285).
    pupil_distance_mm : float
        D = 2 F_min R_max, mm: the distance at which the pupil, measured on the LCoS, gives
        every disc of radius R the F-number D / (2R) (module docstring).

    Examples
    --------
    >>> s = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * 0.01362)
    >>> round(s.f_number(145.5 * 0.01362), 2), round(s.airy_first_zero_px(145.5 * 0.01362), 2)
    (9.85, 1.02)
    """

    wavelength_nm: float
    pixel_pitch_mm: float
    pupil_distance_mm: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "wavelength_nm", check_wavelength(self.wavelength_nm))
        check_positive("pixel_pitch_mm", self.pixel_pitch_mm, "mm")
        check_positive("pupil_distance_mm", self.pupil_distance_mm, "mm")

    @property
    def wavelength_mm(self) -> float:
        return self.wavelength_nm * 1e-6

    @property
    def lag_mm_per_cycle_per_px(self) -> float:
        """lambda D / p: the pupil lag (mm) that an image frequency of 1 cycle/px probes."""
        return self.wavelength_mm * self.pupil_distance_mm / self.pixel_pitch_mm

    def f_number(self, radius_mm: float) -> float:
        """N = D / (2R) of a disc of radius R mm: F_min R_max / R on the paper's scale."""
        return self.pupil_distance_mm / (2.0 * check_positive("radius_mm", radius_mm, "mm"))

    def lambda_n_px(self, radius_mm: float) -> float:
        """lambda N / p of a disc of radius R mm, px: the length that scales its Airy pattern."""
        return self.wavelength_mm * self.f_number(radius_mm) / self.pixel_pitch_mm

    def cutoff_cycles_per_px(self, radius_mm: float) -> float:
        """The disc's incoherent cut-off frequency p / (lambda N), cycles/px (Goodman 6-31)."""
        return 1.0 / self.lambda_n_px(radius_mm)

    def airy_first_zero_px(self, radius_mm: float) -> float:
        """The first dark ring of the disc's Airy pattern, 1.22 lambda N / p, px."""
        return AIRY_FIRST_ZERO * self.lambda_n_px(radius_mm)


def scale_for(design, wavelength_nm: float, pixel_pitch_mm: float | None = None):
    """The :class:`DiffractionScale` of a camera design at one wavelength.

    Parameters
    ----------
    design : CameraDesign
        Supplies F_min, R_max_mm and pixel_pitch_mm (D = 2 F_min R_max).
    wavelength_nm : float
        nm, in [300, 1100].
    pixel_pitch_mm : float, optional
        The pitch of one image pixel, mm; default the design's. A design binned from a larger
        sensor keeps the native 6.45 um pitch (``../shared/ARCHITECTURE.md``), so its
        diffraction is in native pixels unless the binned pitch is given here.

    Returns
    -------
    DiffractionScale
    """
    if design.R_max_mm <= 0 or design.F_min <= 0:
        raise ParameterError("design: R_max_mm and F_min must be > 0")
    pitch = design.pixel_pitch_mm if pixel_pitch_mm is None else pixel_pitch_mm
    return DiffractionScale(
        float(wavelength_nm), float(pitch), 2.0 * float(design.F_min) * float(design.R_max_mm)
    )
