"""Thin-lens projection of the programmable-aperture camera (paper Sections 2.1-2.2).

Units: scene lengths in mm, image quantities in px. The aperture (LCoS) is modelled, as in the
paper's Fig. 3, as the stop of a thin lens at Z = 0, so an aperture offset of X_a mm shifts the
image of a point at depth Z by -beta * X_a on the (inverted) sensor (Eq. 8).

Image coordinates: every image-space quantity in pacam_render (PSFs, s, a_i, offsets) is in
*upright* image coordinates u = -x, as the image is displayed. There Eq. 8 reads
u = |alpha| X + beta X_a, so the image acceleration is +beta a_a, which is Eq. 10 with its sign:
Eqs. 8 and 10 only agree in that frame.

In pixels the shift per mm of aperture offset is

    beta_px = (1/Z_f - 1/Z) * (W/2) / tan(fov/2)            [px/mm]

for a sensor focused at Z_f. The focal length cancels, and this is exactly the geometry of
Mitsuba's ``thinlens`` sensor. Its sign flips across the focal plane: negative beyond it.
"""

from __future__ import annotations

import math

from ..errors import ParameterError, check_positive, check_range

LCOS_PITCH_MM = 0.01362
"""Pixel pitch of the prototype's LCoS aperture display (SXGA-3DM), mm."""


def alpha(Z_mm: float, Zp_mm: float) -> float:
    """Pinhole magnification alpha = -Z_p / Z (Eq. 3), dimensionless."""
    return -check_positive("Zp_mm", Zp_mm, "mm") / check_positive("Z_mm", Z_mm, "mm")


def image_distance_mm(f_mm: float, Z_mm: float) -> float:
    """In-focus image distance Z_p from 1/f = 1/Z + 1/Z_p (Eq. 7), mm.

    An object at or inside the focal length has no real image: that is an error.
    """
    f = check_positive("f_mm", f_mm, "mm")
    Z = check_positive("Z_mm", Z_mm, "mm")
    if Z <= f:
        raise ParameterError(
            f"Z_mm must be > f_mm = {f:g} mm for a real image (Eq. 7), got {Z_mm!r}"
        )
    return 1.0 / (1.0 / f - 1.0 / Z)


def beta(Zp_mm: float, f_mm: float, Z_mm: float) -> float:
    """Parallax coefficient beta = Z_p (1/f - 1/Z - 1/Z_p) (Eq. 9), mm of image per mm.

    Here Z_p is where the sensor is, not the object's in-focus distance: beta = 0 in focus.
    """
    Zp = check_positive("Zp_mm", Zp_mm, "mm")
    f = check_positive("f_mm", f_mm, "mm")
    Z = check_positive("Z_mm", Z_mm, "mm")
    return Zp * (1.0 / f - 1.0 / Z - 1.0 / Zp)


def focal_length_px(fov_deg: float, width_px: int) -> float:
    """Sensor distance in pixels, (W/2) / tan(fov/2), for a horizontal field of view."""
    fov = check_range("fov_deg", fov_deg, 1e-6, 179.999, "deg")
    w = check_positive("width_px", width_px, "px")
    return 0.5 * w / math.tan(math.radians(fov) / 2.0)


def beta_px_per_mm(Z_mm: float, focus_mm: float, fov_deg: float, width_px: int) -> float:
    """Image shift per mm of aperture offset, (1/Z_f - 1/Z) * f_px, px/mm (signed)."""
    Z = check_positive("Z_mm", Z_mm, "mm")
    Zf = check_positive("focus_distance_mm", focus_mm, "mm")
    return (1.0 / Zf - 1.0 / Z) * focal_length_px(fov_deg, width_px)


def defocus_radius_px(beta_px: float, R_mm: float) -> float:
    """Static PSF (pillbox) radius r = |beta| R (Eq. 12), px."""
    if R_mm < 0 or not math.isfinite(R_mm):
        raise ParameterError(f"R_mm must be >= 0 mm, got {R_mm!r}")
    return abs(beta_px) * R_mm


def focus_for_defocus_mm(
    Z_mm: float, r_px: float, R_mm: float, fov_deg: float, width_px: int, side: str = "far"
) -> float:
    """Focus distance Z_f that gives a static PSF of radius r_px for an object at Z_mm.

    ``side="far"`` focuses behind the object (beta < 0, the sign of Eq. 12's r = -beta R);
    ``side="near"`` focuses in front of it (beta > 0). The far side is impossible when the
    required defocus exceeds that of a lens focused at infinity.
    """
    Z = check_positive("Z_mm", Z_mm, "mm")
    r = check_positive("r_px", r_px, "px")
    R = check_positive("R_mm", R_mm, "mm")
    dinv = r / (R * focal_length_px(fov_deg, width_px))  # |1/Z_f - 1/Z|, 1/mm
    if side == "near":
        return 1.0 / (1.0 / Z + dinv)
    if side != "far":
        raise ParameterError(f"side must be 'far' or 'near', got {side!r}")
    inv = 1.0 / Z - dinv
    if inv <= 0:
        r_inf = R * focal_length_px(fov_deg, width_px) / Z
        raise ParameterError(
            f"a defocus radius r = {r:g} px cannot be reached by focusing beyond the object at "
            f"{Z:g} mm: even focus at infinity gives r = {r_inf:.4g} px; focus in front of the "
            "object instead (side='near'), or open the aperture wider"
        )
    return 1.0 / inv


def f_number_to_radius_mm(f_number: float, f_mm: float) -> float:
    """Aperture radius R = f / (2 N), mm."""
    return check_positive("f_mm", f_mm, "mm") / (2.0 * check_positive("f_number", f_number))


def radius_to_f_number(R_mm: float, f_mm: float) -> float:
    """F-number N = f / (2 R)."""
    return check_positive("f_mm", f_mm, "mm") / (2.0 * check_positive("R_mm", R_mm, "mm"))


def lcos_px_to_mm(n_px: float, pitch_mm: float = LCOS_PITCH_MM) -> float:
    """LCoS display pixels to mm on the aperture plane."""
    return float(n_px) * check_positive("pitch_mm", pitch_mm, "mm")


def mm_to_lcos_px(x_mm: float, pitch_mm: float = LCOS_PITCH_MM) -> float:
    """mm on the aperture plane to LCoS display pixels."""
    return float(x_mm) / check_positive("pitch_mm", pitch_mm, "mm")


def aperture_mm_to_image_px(x_mm: float, beta_px: float) -> float:
    """Upright-image shift (px) caused by an aperture offset of x_mm: +beta_px x (Eq. 8, u = -x)."""
    return beta_px * float(x_mm)
