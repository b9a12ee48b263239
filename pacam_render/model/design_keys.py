"""Every key of a design file (:mod:`.design_file`): its unit, default, valid range and the
``pacam design`` flag that sets it, for the generated reference page
(``docs/reference/design_file.md``) and its test, which checks the list against the keys the
reader accepts and the flags against ``pacam design``'s parser.

The defaults are the paper's prototype's (:func:`~.camera.prototype`), read from it, so the
page cannot drift from the code.
"""

from __future__ import annotations

from dataclasses import dataclass

from .camera import MAX_EXPOSURE_MS, MIN_EXPOSURE_MS, MIN_FOCUS_MM, MIN_OPENING_LCOS_PX, prototype
from .schedule import MAX_PATTERNS


@dataclass(frozen=True)
class DesignKey:
    """One key: ``table`` (``""`` at the top), ``key``, ``unit``, ``field`` (the
    :class:`~.camera.CameraDesign` field whose prototype value is the default, or None),
    ``default`` (when not a field's), ``valid`` (the range, in words), ``flag`` (of
    ``pacam design``, or None) and ``meaning``."""

    table: str
    key: str
    unit: str
    field: str | None
    valid: str
    flag: str | None
    meaning: str
    default: str | None = None


KEYS = (
    DesignKey("", "format", "", None, "1", None, "the file's format version", "1"),
    DesignKey("", "name", "", None, "any text", None, "a label for reports",
              "the file's name"),
    DesignKey("sensor", "width_px", "px", "width_px", "integer >= 1", None,
              "the full sensor's width"),
    DesignKey("sensor", "height_px", "px", "height_px", "integer >= 1", None,
              "the full sensor's height"),
    DesignKey("sensor", "pixel_pitch_mm", "mm", "pixel_pitch_mm", "> 0", None,
              "the sensor's pixel pitch"),
    DesignKey("sensor", "fov_deg", "deg", "fov_deg", "(0, 180)", None,
              "the horizontal field of view"),
    DesignKey("sensor", "preset", "", "sensor_preset", "a sensor preset's name or a .json/.toml "
              "preset file", "--sensor", "the image sensor's noise model; a monochrome one "
              "makes captures grey", "none (the ICX285 stands in for the budget)"),
    DesignKey("lens", "R_max_mm", "mm", "R_max_mm", "> 0", None,
              "the clear aperture's radius (the whole LCoS disc), at F_min"),
    DesignKey("lens", "F_min", "", "F_min", "> 0", None, "the lens's F-number wide open"),
    DesignKey("lens", "focus_distance_mm", "mm", "focus_distance_mm",
              f">= {MIN_FOCUS_MM:g}", "--max-velocity (solved)", "the distance in focus",
              "required"),
    DesignKey("lcos", "pitch_mm", "mm", "lcos_pitch_mm", "> 0", None,
              "the display's pixel pitch (the masks' pixels)"),
    DesignKey("lcos", "rate_fps", "patterns/s", "lcos_rate_fps",
              "> 0, and at least n_patterns / exposure", "--lcos-rate",
              "patterns per second the display can show"),
    DesignKey("exposure", "exposure_ms", "ms", "exposure_ms",
              f"[{MIN_EXPOSURE_MS:g}, {MAX_EXPOSURE_MS:g}]", "--exposure", "the exposure 2T"),
    DesignKey("exposure", "n_patterns", "", "n_patterns", f"integer in [1, {MAX_PATTERNS}]",
              "--n-patterns", "patterns shown in one exposure (a bitmap schedule: its masks')"),
    DesignKey("object", "depth_mm", "mm", "object_depth_mm", f">= {MIN_FOCUS_MM:g}", "--depth",
              "the depth the design is made for"),
    DesignKey("opening", "R_mm", "mm", "R_mm",
              f"(0, R_max_mm], at least {MIN_OPENING_LCOS_PX:g} LCoS px", "--max-velocity "
              "(solved)", "the opening's radius (a bitmap schedule has no [opening]: its masks "
              "are the opening)", "required: one of R_mm, f_number, r_px"),
    DesignKey("opening", "f_number", "", None, ">= F_min", "--f-number",
              "the opening as an F-number: R = F_min R_max / f_number", "or this"),
    DesignKey("opening", "r_px", "px", None, "> 0 (needs focus_distance_mm != depth_mm)",
              "--r-px", "the opening by its defocus radius at the object: R = r / abs(beta)",
              "or this"),
    DesignKey("schedule", "kind", "", None, "parabolic, centres or bitmap",
              "--schedule (centres), --masks (bitmap)",
              "how the opening moves: Eq. 11's parabola, one disc per pattern, or "
              "any LCoS images", "required"),
    DesignKey("schedule", "centres_mm", "mm", None, "n_patterns pairs [x, y], each opening "
              "inside the lens", "--schedule", "kind centres: pattern k's disc centre, x to "
              "the image's right, y downwards", "-"),
    DesignKey("schedule", "masks", "", None, "a folder of images, an image, a .npy or .npz "
              "stack (relative to the file)", "--masks", "kind bitmap: the LCoS patterns "
              "(below: their size, centring and orientation)", "-"),
)  # fmt: skip
"""Every key, in the order the file writes them."""


def key_rows() -> list[dict]:
    """The reference table's rows: ``[table] key``, unit, default, valid range, flag, meaning;
    a default is the prototype's value of the key's field."""

    proto = prototype()
    rows = []
    for k in KEYS:
        if k.field is not None and k.default is None:
            v = getattr(proto, k.field)
            default = f"{v:.6g}" if isinstance(v, float) else str(v)
        else:
            default = k.default or "-"
        rows.append({
            "key": f"[{k.table}] {k.key}" if k.table else k.key,
            "unit": k.unit or "-",
            "default": default,
            "valid": k.valid,
            "flag": k.flag or "- (edit the file)",
            "meaning": k.meaning,
        })  # fmt: skip
    return rows
