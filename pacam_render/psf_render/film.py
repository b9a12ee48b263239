"""The film of a rendered PSF and where its source sits, so that the kernel's centre pixel is
where the analytic kernel puts it (see :mod:`.render`, Registration)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import ParameterError
from ..model.camera import CameraDesign

FILM_MODES = ("window", "crop")


@dataclass
class Film:
    """A PSF render's film (a kernel-sized window, or a crop of the whole film), its field of
    view, and the source's position that registers it."""

    mode: str
    width: int  # film size (the prototype's for crop)
    height: int
    kernel_shape: tuple[int, int]
    fov_deg: float
    crop_offset: tuple[int, int] | None
    source_xy_mm: tuple[float, float]
    origin_film_px: tuple[float, float]

    def mitsuba(self) -> dict:
        d = {
            "type": "hdrfilm",
            "width": self.width,
            "height": self.height,
            "rfilter": {"type": "box"},
            "pixel_format": "luminance",
            "component_format": "float32",
        }
        if self.crop_offset is not None:
            h, w = self.kernel_shape
            d.update(
                crop_width=w,
                crop_height=h,
                crop_offset_x=self.crop_offset[0],
                crop_offset_y=self.crop_offset[1],
            )
        return d

    def sample_pixels(self, integrator: str) -> int:
        """Pixels that Mitsuba multiplies by spp: the full film's for ptracer (even with a
        crop), the crop's for camera-ray integrators."""
        if integrator == "ptracer":
            return self.width * self.height
        h, w = self.kernel_shape
        return h * w

    def key(self, integrator: str, exposure_ms: float) -> tuple:
        return (
            integrator,
            self.mode,
            self.width,
            self.height,
            self.kernel_shape,
            self.crop_offset,
            round(self.fov_deg, 12),
            exposure_ms,
        )

    def describe(self, design: CameraDesign) -> dict:
        h, w = self.kernel_shape
        out = {
            "mode": self.mode,
            "width_px": self.width,
            "height_px": self.height,
            "fov_deg": self.fov_deg,
            "focal_length_px": design.focal_length_px,
            "kernel_origin_on_film_px": list(self.origin_film_px),
            "source_offset_mm": list(self.source_xy_mm),
        }
        if self.crop_offset is not None:
            out["crop"] = {
                "offset_x": self.crop_offset[0],
                "offset_y": self.crop_offset[1],
                "width": w,
                "height": h,
            }
            out["registration"] = (
                f"kernel pixel (i, j) is film pixel ({self.crop_offset[1]} + i, "
                f"{self.crop_offset[0]} + j) of the {self.width}x{self.height} prototype film"
            )
        else:
            out["registration"] = (
                "a film of the kernel's size with the prototype's focal length in px; the "
                "source is displaced so that its t = 0 image is the centre of pixel (h//2, w//2)"
            )
        return out


def film_for(design: CameraDesign, centre_px: float, shape, film_mode: str) -> Film:
    """Film and source placement that put image position ``centre_px`` (film columns from the
    point's pinhole image, at mid-exposure) on the centre of kernel pixel (h//2, w//2)."""
    h, w = shape
    if h % 2 == 0 or w % 2 == 0:
        raise ParameterError(f"kernel size must be odd (h, w), got {shape}")
    W, H = design.width_px, design.height_px
    if h > H - 1 or w > W - 1:
        raise ParameterError(
            f"a rendered PSF must fit the {W}x{H} film: kernel side at most {W - 1} x "
            f"{H - 1} px (odd), got {w} x {h}; lower `size`, `velocity` or the defocus"
        )
    Z, f = design.object_depth_mm, design.focal_length_px
    if film_mode == "window":
        # film of the kernel's size, same focal length in px; centre (w/2, h/2) = centre of
        # pixel (h//2, w//2). Pinhole image u = w/2 - f X / Z; the centre at u + centre_px.
        fov = 2.0 * math.degrees(math.atan(0.5 * w / f))
        x_mm = centre_px * Z / f
        return Film("window", w, h, (h, w), fov, None, (x_mm, 0.0), (0.5 * W, 0.5 * H))
    if film_mode != "crop":
        raise ParameterError(f"film must be one of {', '.join(FILM_MODES)}, got {film_mode!r}")
    u_nat = 0.5 * W + centre_px  # where the kernel centre falls for an on-axis point
    j0, i0 = math.floor(u_nat), math.floor(0.5 * H)
    x_mm = (u_nat - (j0 + 0.5)) * Z / f  # u = W/2 - f X/Z + centre_px = j0 + 1/2
    y_mm = (0.5 * H - (i0 + 0.5)) * Z / f  # v = H/2 - f Y/Z = i0 + 1/2
    ox, oy = j0 - w // 2, i0 - h // 2
    if ox < 0 or oy < 0 or ox + w > W or oy + h > H:
        raise ParameterError(
            f"the {w}x{h} kernel around film pixel ({j0}, {i0}) leaves the {W}x{H} film; "
            f"lower `size` or use `film` 'window'"
        )
    fov = design.fov_deg
    return Film("crop", W, H, (h, w), fov, (ox, oy), (x_mm, y_mm), (j0 + 0.5, i0 + 0.5))
