"""The design report: every derived quantity, the pattern schedule, and what does not add up.

``consistency_notes`` is where the paper's published figures are checked against its own
equations; it never hides a disagreement, it quantifies it.

A designed schedule (``pattern_centres_mm``) is not Eq. 11's parabola: its a_i and invariant
range are fitted to its own image trajectory (:func:`~.schedule_fit.schedule_figures`), and
Eq. 18's figures are shown beside them only as the parabola's at the same opening. The
parabola gets Eq. 18's figures with the fitted ones beside them for comparison.
"""

from __future__ import annotations

import math

import numpy as np

from . import paper
from .camera import CameraDesign, prototype
from .schedule_fit import schedule_figures

FITTED = "fitted to the schedule's image trajectory"
"""How the report labels the figures of :func:`~.schedule_fit.schedule_figures`."""


def _rows(d: CameraDesign, fig: dict | None = None) -> list[tuple[str, str, float, str, str]]:
    """(quantity, symbol, value, unit, source)."""
    fig = schedule_figures(d) if fig is None else fig
    return [*_optics_rows(d), *_motion_rows(d, fig)]


def _paper(value, published, where: str) -> str:
    """The source of a design value: the paper's table or section where it is the paper's
    value, else the design's own (a design file or a solved design is not Table 1)."""
    return where if np.allclose(value, published, rtol=1e-9, atol=0.0) else "this design"


def _optics_rows(d: CameraDesign) -> list[tuple[str, str, float, str, str]]:
    size = (d.width_px, d.height_px)
    return [
        ("image size", "W x H", f"{d.width_px} x {d.height_px}", "px",
         _paper(size, (paper.WIDTH_PX, paper.HEIGHT_PX), "Table 1")),
        ("field of view (horizontal)", "fov", d.fov_deg, "deg",
         _paper(d.fov_deg, paper.FOV_DEG, "Table 1")),
        ("sensor distance", "Z_p", d.Z_p_mm, "mm", "fov, 6.45 um pixels"),
        ("sensor distance in pixels", "f_px", d.focal_length_px, "px", "(W/2)/tan(fov/2)"),
        ("thin-lens focal length", "f", d.lens_focal_length_mm, "mm", "Eq. 7"),
        ("object depth", "Z", d.object_depth_mm, "mm",
         _paper(d.object_depth_mm, paper.OBJECT_DEPTH_MM, "Sec. 4")),
        ("focus distance", "Z_f", d.focus_distance_mm, "mm", "derived from r"),
        ("magnification", "alpha", d.alpha, "", "Eq. 3"),
        ("parallax coefficient", "beta", d.beta, "mm/mm", "Eq. 9"),
        ("image shift per aperture mm", "beta_px", d.beta_px_per_mm, "px/mm", "Eq. 9 in px"),
        ("clear aperture radius", "R_max", d.R_max_mm, "mm", f"F{d.F_min:g}"),
        ("  in LCoS pixels", "", d.R_max_mm / d.lcos_pitch_mm, "LCoS px", ""),
        ("opening radius", "R", d.R_mm, "mm", f"F{d.F_number:.3g}"),
        ("  in LCoS pixels", "", d.R_mm / d.lcos_pitch_mm, "LCoS px",
         _paper(d.R_mm / d.lcos_pitch_mm, paper.OPENING_LCOS_PX, "Sec. 4")),
        ("open area", "pi R^2", d.open_area_mm2, "mm^2", "light ~ area"),
        ("static PSF radius", "r", d.r_px, "px", "Eq. 12"),
        ("exposure", "2T", d.exposure_ms, "ms", _paper(d.exposure_ms, paper.EXPOSURE_MS, "Sec. 4")),
        ("patterns", "n", d.n_patterns, "", f"{d.pattern_rate_fps:.4g} per s"),
    ]  # fmt: skip


def _or_undefined(v):
    return "undefined" if v is None else v


def _off_centre(centre: float | None, half_width: float | None) -> bool:
    """The fitted range is centred away from s = 0 by more than 0.1 % of its half-width."""
    return centre is not None and abs(centre) > 1e-3 * max(half_width or 0.0, 1e-6)


def _motion_rows(d: CameraDesign, fig: dict) -> list[tuple[str, str, float, str, str]]:
    """The aperture's motion and what it does to the image: Eq. 15-18 for the parabola,
    the fit to the held patterns' offsets for both (the only figures of a designed one)."""
    n = d.n_patterns
    a_fit = fig["a_i_fitted_px_per_ms2"]
    fitted = [
        ("image acceleration, fitted", "a_i", _or_undefined(a_fit), "px/ms^2", FITTED),
        ("invariant speed range, fitted", "|s| <=",
         _or_undefined(fig["velocity_range_fitted_px_per_ms"]), "px/ms", "|a_i| T, fitted"),
        ("fit RMS residual", "", _or_undefined(fig["fit_rms_residual_px"]), "px",
         f"{n} patterns, {fig['fit_dof']} dof" if fig["fit_dof"] is not None
         else f"{n} held patterns (a parabola needs 3)"),
    ]  # fmt: skip
    centre = fig["velocity_centre_fitted_px_per_ms"]
    if _off_centre(centre, fig["velocity_range_fitted_px_per_ms"]):
        fitted.insert(2, ("  range centred on", "s_c", centre, "px/ms", "-b of the fit"))
    light = ("open fraction", "", fig["open_fraction"], "", "open area / pi R_max^2, time mean")
    if not d.designed:
        return [
            ("aperture travel", "dX_a", d.delta_X_a_mm, "mm", "Eq. 15"),
            ("aperture acceleration", "a_a", d.a_a_mm_per_ms2, "mm/ms^2", "Eq. 17"),
            ("image acceleration", "a_i", d.a_i_px_per_ms2, "px/ms^2", "Eq. 18"),
            ("invariant speed range", "|s| <=", d.velocity_range_px_per_ms, "px/ms", "|a_i| T"),
            *fitted,
            light,
        ]
    x = d.pattern_centres_xy_mm()[:, 0]
    x = x[np.isfinite(x)]  # a dark bitmap pattern has no centre
    travel = float(x.max() - x.min()) if x.size else 0.0
    return [
        ("aperture travel", "dX_a", travel, "mm", "the schedule's centres"),
        *fitted,
        light,
        ("Eq. 18 parabola's a_i", "", d.a_i_px_per_ms2, "px/ms^2", "same R; not this schedule"),
        ("  its invariant range", "", d.velocity_range_px_per_ms, "px/ms", "not this schedule"),
    ]


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    return f"{v:.6g}"


def schedule_notes(d: CameraDesign, fig: dict | None = None) -> list[str]:
    """What the figures of the schedule's motion are: Eq. 18's, or fitted to the schedule."""
    fig = schedule_figures(d) if fig is None else fig
    n = d.n_patterns
    a_fit = fig["a_i_fitted_px_per_ms2"]
    eq18 = f"{d.a_i_px_per_ms2:.4g} px/ms^2 (range {d.velocity_range_px_per_ms:.4g} px/ms)"
    if a_fit is None:
        head = f"No fitted a_i: {fig['fit_undefined_reason']}."
        return [head + (f" Eq. 18's {eq18} is the parabola's, not this schedule's." if
                        d.designed else "")]  # fmt: skip
    fitted = (
        f"a_i = {a_fit:.4g} px/ms^2, range |s| <= {fig['velocity_range_fitted_px_per_ms']:.4g} "
        f"px/ms, RMS residual {fig['fit_rms_residual_px']:.3g} px"
    )
    how = (
        f"a parabola whose window means match the {n} held image offsets "
        "(beta_px x centre) best, in least squares"
    )
    if d.designed:
        return [
            f"A designed schedule of {n} patterns is not Eq. 11's parabola: its figures are "
            f"{FITTED} ({how}): {fitted}. Eq. 18 at the same opening would give {eq18}: that "
            "is the parabola's, not this schedule's."
        ]
    diff = (a_fit / d.a_i_px_per_ms2 - 1.0) if d.a_i_px_per_ms2 else 0.0
    return [
        f"Fitted to the {n} held patterns' image trajectory ({how}): {fitted}; Eq. 18 gives "
        f"{d.a_i_px_per_ms2:.4g} px/ms^2 (relative difference {diff:.1e}): patterns centred "
        "on the parabola at their windows' mid-times keep its curvature exactly."
    ]


def _focus_note(d: CameraDesign) -> str:
    """Where the focus comes from: the paper does not publish the prototype's; another design
    has its own (its file's, or the solver's)."""

    side = "behind" if d.beta_px_per_mm < 0 else "in front of"
    where = f"r = |beta| R = {d.r_px:.3g} px at Z = {d.object_depth_mm:g} mm ({side} the object)"
    if d.digest() == prototype().digest():
        return f"Focus is not published: Z_f = {d.focus_distance_mm:.1f} mm is derived so that {where}."  # noqa: E501
    return f"Focus: Z_f = {d.focus_distance_mm:.1f} mm, this design's, gives {where}."


def consistency_notes(d: CameraDesign) -> list[str]:
    """Which published figures cannot all hold at once, with the numbers."""
    notes = [
        "Image coordinates are upright (as displayed): there an aperture offset X_a shifts the "
        "image by +beta X_a and a_i = beta a_a (Eq. 10) holds with its sign; Eq. 8's -beta is "
        "the inverted sensor frame.",
        _focus_note(d),
        f"One thin lens cannot have both a {d.fov_deg:g} deg field on the 8.26 mm ICX285 "
        f"(f = {d.lens_focal_length_mm:.2f} mm) and F{d.F_min:g} at a "
        f"{d.R_max_mm:.2f} mm radius (f = {d.f_number_focal_mm:.1f} mm): the relay optics make "
        "the LCoS a magnified pupil. As in the paper's Fig. 3 the LCoS is taken as the lens "
        "aperture; r, a_i and the speed range do not depend on this choice, only Z_f does.",
    ]
    quoted = d.quoted_a_i_px_per_ms2
    if quoted is None:
        return notes
    a = abs(d.a_i_px_per_ms2)
    T = d.T_ms
    k = d.R_max_mm / d.R_mm - 1.0  # a_i = 4 r k / T^2
    r_need = quoted * T**2 / (4.0 * k)
    F_need = d.F_min * (1.0 + quoted * T**2 / (4.0 * d.r_px))
    T_need = math.sqrt(4.0 * d.r_px * k / quoted)
    notes += [
        f"The paper quotes a_i = {quoted:g} px/ms^2; Eq. 18 with r = {d.r_px:.3g} px, "
        f"F{d.F_number:.3g} and 2T = {d.exposure_ms:g} ms gives {a:.4g} px/ms^2 "
        f"({quoted / a:.2f}x less). With T = 2T = {d.exposure_ms:g} ms it would be "
        f"{a / 4:.4g}; only 2T = {2 * T_need:.1f} ms (T = {T_need:.1f} ms) gives {quoted:g}.",
        f"To reach {quoted:g} px/ms^2 in {d.exposure_ms:g} ms: r = {r_need:.2f} px at "
        f"F{d.F_number:.3g}, or F{F_need:.1f} at r = {d.r_px:.3g} px.",
        f"The invariant range is then |s| <= {d.velocity_range_px_per_ms:.3g} px/ms: it does not "
        "cover the 1.4 px/ms near train (nor the 1.0 px/ms far one); the paper's "
        f"{quoted:g} would give {quoted * T:.2f} px/ms.",
    ]
    return notes


def pattern_table_text(d: CameraDesign) -> str:
    """The schedule, one row a pattern; a designed schedule that leaves the x axis also gets
    its y centres and vertical image shifts."""
    head = f"{'k':>3} {'t_start':>8} {'t_end':>8} {'X_a mm':>8} {'X_a LCoS px':>11} {'shift px':>9}"
    xy = d.pattern_centres_xy_mm()
    two_d = bool(np.any(np.abs(xy[:, 1]) > 1e-9))  # mm (a bitmap's centroid: rounding)
    head += f" {'Y_a mm':>8} {'v shift px':>10}" if two_d else ""
    lines = [head, "-" * len(head)]
    for row, y in zip(d.pattern_table(), xy[:, 1]):
        lines.append(
            f"{row['k']:>3} {row['t_start_ms']:>8.3f} {row['t_end_ms']:>8.3f} "
            f"{row['centre_mm']:>8.4f} {row['centre_lcos_px']:>11.2f} "
            f"{row['image_offset_px']:>9.3f}"
            + (f" {y:>8.4f} {d.beta_px_per_mm * y:>10.3f}" if two_d else "")
        )
    return "\n".join(lines)


def design_report(d: CameraDesign) -> str:
    """A readable, plain-text report of the design."""
    title = f"pacam_render design report: {d.name}"
    fig = schedule_figures(d)
    rows = _rows(d, fig)
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    body = [f"{q:<{w0}}  {sym:<{w1}}  {_fmt(v):>12} {u:<8} {src}" for q, sym, v, u, src in rows]
    notes = [f"- {n}" for n in (*schedule_notes(d, fig), *consistency_notes(d))]
    return "\n".join(
        [
            title,
            "=" * len(title),
            *body,
            "",
            f"Aperture schedule: {d.n_patterns} patterns "
            f"({'designed' if d.designed else 'the parabola of Eq. 11'}; times in ms, t = 0 at "
            "mid-exposure)",
            pattern_table_text(d),
            "",
            "Notes",
            *notes,
        ]
    )
