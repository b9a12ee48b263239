"""A capture's physics error budget, ``capture.json``'s ``optics_error`` (issue 36, item 4).

Next to ``render_error`` (the Monte Carlo error, which the render controls), each effect that
rays through an ideal aperture leave out, or include only approximately, gets an entry:

``included``      whether the capture has it;
``how``           how it is included, or why it is left out;
``approximation`` the error of how it is included (where it is), in its own terms;
``size_rms``      its estimated size on this capture where it is left out: RMS over the
                  window in the capture's units (measured on the image where it can be, an
                  estimate otherwise, ``estimate`` says which);
``ratio_to_sensor`` ``size_rms`` over the sensor's temporal noise at the capture's mean level
                  (``reference_noise`` names the sensor; ``pacam render --sensor`` replaces it
                  with the capture's own).

The effects: ``diffraction`` (:mod:`pacam_render.exposure.optics.diffraction`),
``relative_illumination`` (:mod:`pacam_render.model.illumination`), the LCoS's ``lcos_leakage``
(finite contrast), ``lcos_grid`` (the pixel grid's diffraction orders) and ``lcos_switching`` (the
time between patterns), and ``bounces`` past the integrator's ``max_depth``. The LCoS is ideal by
default (infinite contrast, fill factor 1, instant switching: no datasheet value is known for the
prototype's display); a finite ``lcos_contrast`` puts the leakage in the rays. An ideal
effect's entry states its sensitivity instead: the contrast, fill factor and switching time
at which it would equal the sensor's noise, from closed forms on this capture's image:

- leakage adds (full-aperture image - coded image) / contrast; the full-aperture image is
  taken as the capture scaled to the full aperture's light (its defocus differs: an estimate);
- a grid of area fill factor f sends (1 - f) of the transmitted light into ghost orders at
  lambda f_lens / pitch (about 244 px at 550 nm for the prototype): (1 - f) x RMS(image);
- switching of time t between N patterns blends neighbours for (N - 1) t / E of the exposure:
  at most that fraction x RMS(image) (an upper bound).
"""

from __future__ import annotations

import numpy as np

from ..render.ray_diffraction import MAX_ORDER, grid_orders

EFFECTS = (
    "diffraction",
    "relative_illumination",
    "lcos_leakage",
    "lcos_grid",
    "lcos_switching",
    "bounces",
)
"""The entries of ``optics_error``, in order."""

TYPICAL_LCOS = {"lcos_leakage": 1000.0, "lcos_switching": 0.1}
"""A typical LCoS microdisplay, against which an ideal one is sized (issue 46, item 5): a
contrast of 1000:1 and a switching time of 0.1 ms (a ferroelectric panel, as 16 patterns in
45 ms need; nematic panels take milliseconds). Where such a device's effect would exceed the
sensor's noise, the ideal entry says so (``size_rms_at_typical``, ``typical_matters``) and
:func:`largest_left_out` weighs it at that size. The pixel grid is not weighed so: its ghosts
land ~244 px away as a near-uniform veil, whose closed form, (1 - f) x RMS(image), is an
upper bound that would name it on nearly every capture."""
TYPICAL_BLEND = 0.1
"""The share of the exposure a typical panel's switching must blend before its (loose) bound is
weighed: the prototype's 16 patterns in 45 ms blend 3 %, 64 patterns in 20 ms 32 %."""
BOUNCE_SHARE = {"train": 8e-4, "soccer": 9e-5, "walker": 1.2e-3}
"""Share of a built-in scene's light that paths past ``max_depth`` 3 add, measured noise-free by
``benchmarks/bench_render_error.py`` (part 3; ``benchmarks/RESULTS.md``)."""
BOUNCE_DEPTH = 3


def image_rms(image) -> float:
    """RMS of an image's values over the window and channels."""
    return float(np.sqrt(np.mean(np.square(np.asarray(image, float)))))


def entry(included: bool, how: str, size=None, estimate: str | None = None, **extra) -> dict:
    """One effect's entry (module docstring); ``size`` in the capture's units."""
    out = {"included": bool(included), "how": how, "size_rms": size}
    if estimate:
        out["estimate"] = estimate
    out.update(extra)
    return out


def relative_illumination_entry(image, cos4_map, ri_record: dict | None) -> dict:
    """Included: the cos^4 law's departure from the exact thin lens at the window's corner.
    Left out: RMS of image x (1 - cos^4) over the window, measured."""
    if ri_record is not None:
        exact = ri_record.get("thin_lens_exact_over_cos4_at_corner")
        approx = None if exact is None else abs(exact - 1.0)
        return entry(True, ri_record["law"], approximation=approx)
    if cos4_map is None:  # the pinhole reference: no lens
        return entry(False, "not applicable: the reference is a pinhole", 0.0)
    m = np.asarray(cos4_map, float)
    m = m[..., None] if np.ndim(image) == 3 else m
    size = image_rms(np.asarray(image, float) * (1.0 - m))
    return entry(
        False, "off: radiance, as Mitsuba's thinlens", size, "measured: image x (1 - cos^4)"
    )


NOT_APPLIED = "{flag} = {value:g} was asked but is not in the rays: the capture's schedule {why}"
"""How an LCoS entry reads when its value was asked for a schedule that does not model it."""


def leakage_entry(
    image, full_over_coded: float, contrast: float | None = None, asked: float | None = None
) -> dict:
    """In the rays at a finite ``contrast``; else ideal (infinite contrast), with the size per
    1 / contrast (module docstring). ``asked``: a contrast given for a schedule that shows no
    disc (a bitmap, the flutter shutter, Levin's camera): sized at that contrast."""
    per = image_rms(image) * max(full_over_coded - 1.0, 0.0)
    if asked is not None and contrast is None:
        why = NOT_APPLIED.format(flag="lcos_contrast", value=asked, why="shows no disc to leak")
        return entry(False, why, per / asked, "closed form: (full-aperture - coded) / contrast",
                     asked=asked, size_rms_per_inverse_contrast=per)  # fmt: skip
    if contrast is not None:
        return entry(
            True,
            f"in the rays: the lens outside the opening passes 1/{contrast:g} of the light",
            contrast=contrast,
            approximation=0.0,
            size_rms_per_inverse_contrast=per,
        )
    return entry(
        False,
        "ideal LCoS: infinite contrast (no datasheet value known)",
        0.0,
        "closed form: (full-aperture - coded) / contrast",
        size_rms_per_inverse_contrast=per,
    )


def grid_entry(image, fill_factor: float | None = None) -> dict:
    """In the rays at a ``fill_factor`` < 1; else ideal (fill factor 1), with the ghosts' size
    per (1 - fill factor)."""
    if fill_factor is not None:
        _, lost = grid_orders(fill_factor)
        return entry(
            True,
            f"in the rays: orders |m| <= {MAX_ORDER} per axis, f sinc^2(m f) of the light "
            f"each, at m lambda D / pitch (fill factor {fill_factor:g})",
            approximation=lost,
            fill_factor=fill_factor,
            size_rms_per_unfilled_fraction=image_rms(image),
        )
    return entry(
        False,
        "ideal LCoS: fill factor 1, no grid orders (no datasheet value known)",
        0.0,
        "closed form: (1 - fill factor) of the light into orders at lambda f / pitch",
        size_rms_per_unfilled_fraction=image_rms(image),
    )


def switching_entry(image, n_patterns: int, exposure_ms: float, t_ms=None, asked=None) -> dict:
    """In the rays at a switching time ``t_ms``; else ideal (instant), with an upper bound of
    the size per ms of switching time. ``asked``: a switching time given for a schedule that
    switches no disc (a bitmap, a continuous parabola): bounded at that time."""
    frac = max(n_patterns - 1, 0) / exposure_ms
    if asked and not t_ms:
        why = NOT_APPLIED.format(flag="lcos_switching_ms", value=asked, why="switches no disc")
        return entry(False, why, frac * asked * image_rms(image),
                     "upper bound: (N - 1) t / E of the exposure blends neighbouring patterns",
                     asked=asked, size_rms_per_ms=frac * image_rms(image))  # fmt: skip
    if t_ms:
        return entry(
            True,
            f"in the rays: {t_ms:g} ms of linear change from each pattern to the next",
            approximation=0.0,
            switching_ms=t_ms,
            size_rms_per_ms=frac * image_rms(image),
        )
    return entry(
        False,
        "ideal LCoS: patterns switch instantly (no datasheet value known)",
        0.0,
        "upper bound: (N - 1) t / E of the exposure blends neighbouring patterns",
        size_rms_per_ms=frac * image_rms(image),
        blend_per_ms=frac,
    )


def bounces_entry(image, scene: str, integrator: dict | None) -> dict:
    """The light past ``max_depth``: measured for the built-in scenes at depth 3."""
    # a scene file's own integrator arrives as a Mitsuba object: its depth is not readable
    depth = integrator.get("max_depth") if isinstance(integrator, dict) else None
    how = f"left out: paths past max_depth {depth}"
    share = BOUNCE_SHARE.get(scene) if depth == BOUNCE_DEPTH else None
    if share is None:
        return entry(
            False, how, None, "not measured for this scene and depth: "
            "benchmarks/bench_render_error.py measures it",
        )  # fmt: skip
    return entry(
        False, how, share * image_rms(image),
        f"{share:.2g} of the light (bench_render_error, part 3) x RMS(image)",
    )  # fmt: skip


def add_ratios(block: dict, noise_sigma: float | None, where: str, own: bool = True) -> None:
    """Each entry's sizes over the sensor's noise, and the LCoS values at which an ideal
    effect would equal it; ``where`` names the sensor, ``own`` says whether it is the
    capture's (its sensor model or noise target) or a stand-in."""
    block["reference_noise"] = {"sigma": noise_sigma, "sensor": where, "stand_in": not own}
    ok = noise_sigma is not None and noise_sigma > 0
    for e in block["effects"].values():
        size = e.get("size_rms")
        e["ratio_to_sensor"] = size / noise_sigma if ok and size is not None else None
    lcos = block["effects"]
    if ok:
        per = lcos["lcos_leakage"]["size_rms_per_inverse_contrast"]
        lcos["lcos_leakage"]["contrast_at_sensor_noise"] = per / noise_sigma if per else None
        per = lcos["lcos_grid"]["size_rms_per_unfilled_fraction"]
        lcos["lcos_grid"]["fill_factor_at_sensor_noise"] = 1 - noise_sigma / per if per else None
        per = lcos["lcos_switching"]["size_rms_per_ms"]
        lcos["lcos_switching"]["switching_ms_at_sensor_noise"] = noise_sigma / per if per else None
        _typical_lcos(lcos, noise_sigma)
    block["largest_left_out"] = largest_left_out(block)


def _typical_lcos(effects: dict, noise_sigma: float) -> None:
    """Each ideal LCoS entry's size at a typical device (:data:`TYPICAL_LCOS`), and whether it
    would exceed the sensor's noise there."""
    per = {
        "lcos_leakage": effects["lcos_leakage"]["size_rms_per_inverse_contrast"]
        / TYPICAL_LCOS["lcos_leakage"],
        "lcos_switching": effects["lcos_switching"]["size_rms_per_ms"]
        * TYPICAL_LCOS["lcos_switching"],
    }
    blend = effects["lcos_switching"].get("blend_per_ms", 0.0) * TYPICAL_LCOS["lcos_switching"]
    for k, size in per.items():
        e = effects[k]
        if e["included"] or not size or "asked" in e:  # an asked value is sized at itself
            continue
        e["size_rms_at_typical"] = size
        # switching's size is a loose bound (neighbouring patterns differ little): it is
        # weighed only where a typical panel blends a tenth of the exposure or more
        loose = k == "lcos_switching" and blend < TYPICAL_BLEND
        e["typical_matters"] = bool(size > noise_sigma and not loose)


def largest_left_out(block: dict) -> str | None:
    """The left-out effect of the largest size (None when every one is 0 or unknown): an
    effect left out, or the part an included effect's approximation leaves out
    (``residual``)."""
    sizes = {
        k: e["size_rms"]
        for k, e in block["effects"].items()
        if (not e["included"] or e.get("residual")) and e.get("size_rms")
    }
    for k, e in block["effects"].items():  # an ideal LCoS that a typical device would not be
        if e.get("typical_matters"):
            sizes[k] = max(sizes.get(k, 0.0), e["size_rms_at_typical"])
    return max(sizes, key=sizes.get) if sizes else None


def summary_line(block: dict | None) -> str | None:
    """One line: the largest left-out effect and its size against the sensor's noise."""
    if not block or not block.get("largest_left_out"):
        return None
    k = block["largest_left_out"]
    e = block["effects"][k]
    what = k.replace("_", " ")
    if e.get("typical_matters"):
        return _typical_line(k, e, block)
    ratio = e.get("ratio_to_sensor")
    vs = f", {ratio:.2g}x {_noise_words(block)}" if ratio is not None else ""
    if e.get("residual"):
        scale = str(e.get("estimate", "")).startswith("scale")
        what += (
            " (the scale of what rays cannot do at occluding edges, not a bound)"
            if scale
            else " (what its approximation leaves out)"
        )
    elif k == "diffraction" and (block.get("diffraction") or {}).get("setting") == "auto":
        what += " (measured on the capture; auto decided on its preview)"
    if e.get("asked") is not None:
        what += f" at the asked {e['asked']:g} (not in the rays: the schedule has none)"
    return f"optics left out: largest is {what}, RMS {e['size_rms']:.3g}{vs}"


_TYPICAL_WORDS = {
    "lcos_leakage": ("contrast {:g}:1", "lcos_contrast", "contrast_at_sensor_noise"),
    "lcos_switching": (
        "switching time {:g} ms",
        "lcos_switching_ms",
        "switching_ms_at_sensor_noise",
    ),
}


def _typical_line(k: str, e: dict, block: dict) -> str:
    """The summary when an ideal LCoS entry matters at a typical device."""
    device, flag, at_noise = _TYPICAL_WORDS[k]
    sigma = block["reference_noise"]["sigma"]
    return (
        f"optics left out: largest is an ideal LCoS's {k.removeprefix('lcos_')}: a typical "
        f"device ({device.format(TYPICAL_LCOS[k])}) would add RMS {e['size_rms_at_typical']:.3g}, "
        f"{e['size_rms_at_typical'] / sigma:.2g}x {_noise_words(block)} (it equals the noise at "
        f"{e[at_noise]:.3g}); give the display's value as `{flag}`"
    )


def _noise_words(block: dict) -> str:
    """The noise the sizes are over: the capture's sensor's, or a named stand-in's."""
    ref = block.get("reference_noise") or {}
    if not ref.get("stand_in"):
        return "the sensor's noise"
    return f"the noise of a stand-in sensor ({ref['sensor']}; the capture has none)"
