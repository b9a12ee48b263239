"""What a schedule does to the image, measured from the schedule itself (issue 35, item 3).

Eq. 18's a_i = 4 beta (R_max - R) / T^2 and its range |a_i| T describe the paper's parabola
(Eq. 11). A designed schedule (``CameraDesign.pattern_centres_mm``, e.g. from
``pacam optimize``) is not that parabola, so its figures must come from its own openings:
:func:`schedule_figures` takes any camera's patterns and returns the image offsets they give,
the parabola fitted to them, and the light the openings let through.

The fit
-------
Pattern k holds the opening still during its window [e_k, e_k+1): a still point images at
u_k = beta_px X_k (Eq. 8, upright frame) for the whole window, so the image path is a step
function. The fitted path is p(t) = u0 + b t + a t^2 / 2, and ``a`` is the schedule's a_i.

Chosen criterion (``"window_mean"``): the parabola whose **window means** match the held
positions, weighted by the windows' durations,

    minimise  sum_k (e_k+1 - e_k) (mean_k p - u_k)^2,
    mean_k p = u0 + b (e_k + e_k+1) / 2 + a (e_k^2 + e_k e_k+1 + e_k+1^2) / 6,

a linear least-squares problem in (u0, b, a), solved in closed form. It is the data part of
the integral criterion  sum_k int_k (p(t) - u_k)^2 dt = sum_k h_k [(mean_k p - u_k)^2 +
var_k p]; the other part, var_k p (how much p moves inside a window), does not depend on the
held positions at all and only pulls the fit towards a flat line. Minimising the whole integral
(``"continuous_l2"``, the L2 projection of the step function on quadratics) therefore
shrinks a: for the paper's parabola sampled at the windows' mid-times it returns

    a_fit / a_i = (1 - 1/N^2) (1 - 4/N^2)            (N equal windows, exact),

0.98053 for N = 16 (-1.95 %), 0.92285 for N = 8, 0 for N = 2, and 1 - 5/N^2 -> 1 as N ->
infinity (derivation: the t^2 part of the projection is its Legendre P2 component, and the
midpoint sums of x^2 and x^4 over the windows are exact by Euler-Maclaurin). With
``"window_mean"`` the paper's parabola gives Eq. 18's a_i exactly for every N: a window's mean
of a parabola is its mid-time value plus a h^2 / 24, a constant that u0 absorbs. The same holds
for a parabola's window means, so the fit recovers any parabola from either. It also agrees with
how rendered PSFs are measured (:func:`pacam_render.restore.metrics.fit_acceleration`: a
parabola through the per-window centroids at the mid-times, which gives the same a and b for
equal windows).

A held schedule then moves a point of image speed s as x(t) = u0 + (s + b) t + a t^2 / 2
(Eq. 2 plus the fitted linear term), so the invariant speeds are |s + b| <= |a| T: the range
``velocity_range_fitted_px_per_ms`` = |a| T, centred on ``velocity_centre_fitted_px_per_ms``
= -b (0 for a schedule symmetric in time).

A parabola has three coefficients: with fewer than three patterns a is undefined, and the
figures are None with ``fit_undefined_reason`` saying why (never NaN). A dark pattern (a bitmap
with nothing open) images nothing: it is left out of the fit, and its centre and offset are
None.

Keys of :func:`schedule_figures` (``FIGURE_KEYS``): see its docstring.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from . import schedule as sch

CRITERIA = ("window_mean", "continuous_l2")
"""The fit criteria of :func:`fit_held_parabola` (the module's docstring compares them)."""

FIT_METHOD = (
    "least-squares parabola u0 + b t + a t^2/2 whose window means match the held image "
    "offsets u_k (windows weighted by duration); fitted to the schedule's image trajectory"
)
"""``fit_method`` of :func:`schedule_figures`."""

OPEN_AREA_SLACK = 0.01
"""A pattern's open area may exceed the full lens's pi R_max^2 by this fraction (a
pixelated full disc does by a fraction of a percent); more is refused."""

FIGURE_KEYS = (
    "schedule",
    "n_patterns",
    "pattern_edges_ms",
    "pattern_centres_mm",
    "pattern_offsets_px",
    "a_i_fitted_px_per_ms2",
    "velocity_range_fitted_px_per_ms",
    "velocity_centre_fitted_px_per_ms",
    "fit_u0_px",
    "fit_b_px_per_ms",
    "fit_rms_residual_px",
    "fit_dof",
    "fit_method",
    "fit_undefined_reason",
    "open_fraction",
    "open_area_mm2_mean",
    "open_area_source",
)
"""Every key of :func:`schedule_figures`, in order."""


def parabola_fit_ratio(n: int) -> float:
    """a_fit / a_i of the ``"continuous_l2"`` fit for the paper's parabola in ``n`` equal
    windows (centres at the mid-times): (1 - 1/n^2) (1 - 4/n^2). The ``"window_mean"`` fit's
    ratio is 1 for every n >= 3.

    >>> round(parabola_fit_ratio(16), 5), parabola_fit_ratio(2)
    (0.98053, 0.0)
    """
    d2 = 1.0 / sch.check_n_patterns(n) ** 2
    return (1.0 - d2) * (1.0 - 4.0 * d2)


def _undefined_reason(u: np.ndarray, n: int) -> str:
    """Why no parabola: ``u`` the lit windows' positions (fewer than 3), ``n`` all windows."""
    dark = n - len(u)
    lit = f" ({dark} of the {n} dark)" if dark else ""
    if len(u) == 0:
        return f"{n} patterns, all dark: no light, no image trajectory"
    if len(u) == 1:
        return (
            f"{n} patterns{lit}: one held position, the image does not move, so a_i and its "
            "invariant range are undefined"
        )
    jump = abs(float(u[-1] - u[0]))
    moves = (
        f"the image jumps by {jump:.4g} px between them"
        if jump > 1e-9 * max(1.0, float(np.max(np.abs(u))))
        else "here both hold the image at the same place"
    )
    return (
        f"{n} patterns{lit}: a parabola u0 + b t + a t^2/2 has 3 coefficients and 2 held "
        f"positions fix only a line ({moves}), so a_i and its invariant range are undefined"
    )


def fit_held_parabola(edges_ms, u_px, criterion: str = "window_mean", lit=None) -> dict:
    """The parabola p(t) = u0 + b t + a t^2 / 2 fitted to a held (piecewise-constant) path.

    Parameters
    ----------
    edges_ms : array_like
        The n + 1 increasing window edges, ms (pattern k is held on [edges[k], edges[k+1])).
    u_px : array_like
        The n held positions, px (NaN allowed where ``lit`` is False).
    criterion : {"window_mean", "continuous_l2"}
        ``"window_mean"`` (the default, the one reported): p's window means match u_k in the
        least-squares sense, windows weighted by duration. ``"continuous_l2"``: minimise the
        integral of (p(t) - u(t))^2 over the lit windows (biased towards a = 0; see the
        module).
    lit : array_like of bool, optional
        The windows that let light through (a dark bitmap pattern images nothing, so it has
        no position); only these are fitted. None: every window.

    Returns
    -------
    dict
        ``a`` (px/ms^2), ``b`` (px/ms), ``u0`` (px), ``rms_px`` (the duration-weighted RMS of
        mean_k p - u_k for ``"window_mean"``, of p(t) - u(t) over the lit windows for
        ``"continuous_l2"``), ``dof`` (lit windows - 3) and ``reason`` (None); with fewer
        than 3 lit windows every number is None and ``reason`` says why.

    Examples
    --------
    Window means of p(t) = 1 + 0.2 t - 0.05 t^2 / 2 give back a = -0.05:

    >>> e = np.linspace(-4.0, 4.0, 9)
    >>> m1, m2 = (e[:-1] + e[1:]) / 2, (e[:-1] ** 2 + e[:-1] * e[1:] + e[1:] ** 2) / 3
    >>> f = fit_held_parabola(e, 1 + 0.2 * m1 - 0.05 * m2 / 2)
    >>> round(f["a"], 12), round(f["b"], 12), round(f["rms_px"], 12)
    (-0.05, 0.2, 0.0)
    """
    e = np.asarray(edges_ms, dtype=float)
    u = np.asarray(u_px, dtype=float)
    if criterion not in CRITERIA:
        raise ParameterError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    if e.ndim != 1 or u.shape != (len(e) - 1,) or len(u) < 1:
        raise ParameterError(
            f"need n + 1 window edges for n held positions, got {e.shape} and {u.shape}"
        )
    on = np.ones(len(u), bool) if lit is None else np.asarray(lit, dtype=bool)
    if on.shape != u.shape:
        raise ParameterError(f"lit must hold one flag per window ({len(u)}), got {on.shape}")
    if not (np.all(np.isfinite(e)) and np.all(np.diff(e) > 0) and np.all(np.isfinite(u[on]))):
        raise ParameterError("window edges must be finite and increasing, lit positions finite")
    if on.sum() < 3:
        none = dict(a=None, b=None, u0=None, rms_px=None, dof=None)
        return {**none, "reason": _undefined_reason(u[on], len(u))}
    # scaled time x = (t - c) / s keeps the 3 x 3 system well conditioned for any units
    c, s = float(0.5 * (e[0] + e[-1])), float(0.5 * (e[-1] - e[0]))
    x = (e - c) / s
    x0, x1, u = x[:-1][on], x[1:][on], u[on]
    w = x1 - x0
    # window integrals of 1, x, x^2 (rows: lit windows)
    moments = np.stack([w, (x1**2 - x0**2) / 2, (x1**3 - x0**3) / 3], axis=1)
    if criterion == "window_mean":
        A = moments / w[:, None]  # window means of the basis
        sw = np.sqrt(w)
        coef = np.linalg.lstsq(A * sw[:, None], u * sw, rcond=None)[0]
        rms = math.sqrt(float(np.sum(w * (A @ coef - u) ** 2) / np.sum(w)))
    else:
        p = np.arange(5) + 1  # integrals of x^0 .. x^4 over the lit windows
        mom = ((x1[:, None] ** p - x0[:, None] ** p) / p).sum(axis=0)
        gram = np.array([[mom[i + j] for j in range(3)] for i in range(3)])
        rhs = moments.T @ u
        coef = np.linalg.solve(gram, rhs)
        # integral of (p - u)^2 = coef' G coef - 2 coef' rhs + sum_k u_k^2 h_k
        sq = coef @ gram @ coef - 2 * coef @ rhs + np.sum(u**2 * w)
        rms = math.sqrt(max(float(sq), 0.0) / float(np.sum(w)))
    # p = k0 + k1 x + k2 x^2 with x = (t - c) / s  ->  u0 + b t + a t^2 / 2
    k0, k1, k2 = (float(v) for v in coef)
    a = 2.0 * k2 / s**2
    b = k1 / s - 2.0 * k2 * c / s**2
    u0 = k0 - k1 * c / s + k2 * c**2 / s**2
    return dict(a=a, b=b, u0=u0, rms_px=rms, dof=int(on.sum()) - 3, reason=None)


def _open_areas(cam, open_areas_mm2) -> tuple[np.ndarray, str]:
    n = cam.n_patterns
    masks = getattr(cam, "pattern_masks", None)  # a bitmap schedule, where the camera has one
    if open_areas_mm2 is None and masks is not None:
        open_areas_mm2, source = masks.open_areas_mm2(), "the bitmaps' open areas"
    elif open_areas_mm2 is None:
        return np.full(n, math.pi * cam.R_mm**2), "disc of radius R in every pattern"
    else:
        source = "per-pattern open areas (given)"
    a = np.asarray(open_areas_mm2, dtype=float)
    full = math.pi * cam.R_max_mm**2
    if a.shape != (n,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ParameterError(
            f"open_areas_mm2 must be n_patterns = {n} finite areas >= 0 in mm^2, "
            f"got {open_areas_mm2!r}"
        )
    if np.any(a > full * (1 + OPEN_AREA_SLACK)):
        k = int(np.argmax(a))
        raise ParameterError(
            f"open_areas_mm2[{k}] = {a[k]:.6g} mm^2 is more than the lens's pi R_max^2 = "
            f"{full:.6g} mm^2 (count only the open area inside the lens)"
        )
    return a, source


def _pairs(xy: np.ndarray, lit: np.ndarray) -> list:
    """JSON-ready (x, y) pairs; None for a dark pattern (it has no centre)."""
    return [list(map(float, p)) if ok else None for p, ok in zip(xy, lit)]


def schedule_figures(cam, open_areas_mm2=None) -> dict:
    """A schedule's own figures: image offsets, fitted a_i and range, and open fraction.

    Works for any camera: a designed schedule (``pattern_centres_mm``) or the parabola (whose
    centres come out of the same ``cam.pattern_centres_xy_mm()``).

    Parameters
    ----------
    cam : CameraDesign
        Read through ``pattern_centres_xy_mm()``, ``beta_px_per_mm``, ``T_ms``,
        ``n_patterns``, ``R_mm``, ``R_max_mm`` and ``designed`` (this module does not import
        the camera, so the camera may call it).
    open_areas_mm2 : array_like, optional
        Each pattern's open area inside the lens, mm^2 (bitmap schedules). None: the
        camera's bitmaps' areas where it has ``pattern_masks``, else the disc pi R^2 in every
        pattern. A pattern of area 0 is dark: it is left out of the fit.

    Returns
    -------
    dict
        JSON-ready, keys :data:`FIGURE_KEYS`:

        - ``schedule``: "designed" or "parabola"; ``n_patterns``;
        - ``pattern_edges_ms``: the n + 1 window edges (:func:`~.schedule.pattern_edges_ms`);
        - ``pattern_centres_mm``: n pairs (x, y), mm (x right, y down; a bitmap's
          transmittance-weighted centroid); None for a dark pattern;
        - ``pattern_offsets_px``: n pairs (u, v), px: beta_px times the centre, where the
          pattern images a still point relative to its pinhole image (upright frame);
        - ``a_i_fitted_px_per_ms2``: a of the parabola fitted to u (:func:`fit_held_parabola`,
          ``"window_mean"``), signed; None with fewer than 3 lit patterns;
        - ``velocity_range_fitted_px_per_ms``: |a| T, fitted (None likewise);
        - ``velocity_centre_fitted_px_per_ms``: -b, the speed the range is centred on;
        - ``fit_u0_px``, ``fit_b_px_per_ms``: the fit's other coefficients;
        - ``fit_rms_residual_px``: the duration-weighted RMS of (window mean of the fit - u_k);
        - ``fit_dof``: lit patterns - 3 (0: the parabola passes through every one);
        - ``fit_method``: :data:`FIT_METHOD`; ``fit_undefined_reason``: None, or why a_i is
          undefined;
        - ``open_fraction``: the time-averaged open area over the full lens's pi R_max^2;
        - ``open_area_mm2_mean``: the time-averaged open area, mm^2;
        - ``open_area_source``: where the areas came from.

    Examples
    --------
    >>> from pacam_render.model.camera import prototype
    >>> f = schedule_figures(prototype())
    >>> f["n_patterns"], round(f["a_i_fitted_px_per_ms2"], 6), round(f["open_fraction"], 4)
    (16, -0.039805, 0.0808)
    """
    T = cam.T_ms
    n = cam.n_patterns
    edges = sch.pattern_edges_ms(T, n)
    centres = np.asarray(cam.pattern_centres_xy_mm(), dtype=float)
    offsets = cam.beta_px_per_mm * centres  # = modes.pattern_offsets_px(cam), Eq. 8
    areas, source = _open_areas(cam, open_areas_mm2)
    lit = np.all(np.isfinite(centres), axis=1) & (areas > 0)
    fit = fit_held_parabola(edges, offsets[:, 0], lit=lit)
    w = np.diff(edges)
    mean_area = float(np.sum(w * areas) / np.sum(w))
    a = fit["a"]
    return {
        "schedule": "designed" if cam.designed else "parabola",
        "n_patterns": int(n),
        "pattern_edges_ms": edges.tolist(),
        "pattern_centres_mm": _pairs(centres, lit),
        "pattern_offsets_px": _pairs(offsets, lit),
        "a_i_fitted_px_per_ms2": a,
        "velocity_range_fitted_px_per_ms": None if a is None else abs(a) * T,
        "velocity_centre_fitted_px_per_ms": None if fit["b"] is None else 0.0 - fit["b"],
        "fit_u0_px": fit["u0"],
        "fit_b_px_per_ms": fit["b"],
        "fit_rms_residual_px": fit["rms_px"],
        "fit_dof": fit["dof"],
        "fit_method": FIT_METHOD,
        "fit_undefined_reason": fit["reason"],
        "open_fraction": mean_area / (math.pi * cam.R_max_mm**2),
        "open_area_mm2_mean": mean_area,
        "open_area_source": source,
    }
