"""Aperture codes as transmissions: A(u, v, t) of a design, the weight of a store's sample.

A capture is the light field weighed by the design's transmission and integrated over the lens
and the exposure; with samples uniform over the whole lens and the store's exposure, a design's
pixel is the mean over its samples of L x A (the plugin's pixel scale, radiance x open area /
full aperture x exposure / 45 ms, falls out of the uniform density). A is read from the design's
own :class:`~pacam_render.render.plan.AperturePlan`, the plan the plugin renders from, so the
pattern at each time, the openings' centres (held or continuous), bitmaps, closed chops and the
LCoS's contrast mean what they mean in a direct render.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ..render.plan import AperturePlan

SERVED = ("static", "parabolic", "centres", "bitmap", "flutter")
"""The schedules a store serves: every one whose camera does not move."""


def check_served(plan: AperturePlan, params: dict) -> None:
    """Refuse a design that no reweighting of the store's rays can give, naming why."""
    if plan.schedule not in SERVED:
        raise ParameterError(
            f"a light-field store cannot serve schedule {plan.schedule!r}: Levin's camera moves "
            "its body, so its rays are not the store's; render it directly"
        )
    switch = float(params.get("lcos_switching") or 0.0)
    if switch > 0:
        if plan.schedule not in ("parabolic", "centres") or plan.continuous:
            raise ParameterError(
                f"lcos_switching_ms: the {plan.schedule} schedule has no discs switching on "
                "the LCoS (discrete parabolic or centres, as the plugin draws them)"
            )
        width = plan.duration / plan.n_patterns
        if switch > width:
            raise ParameterError(
                f"lcos_switching_ms ({switch:g} ms) must be at most a pattern's time ({width:g} "
                f"ms = the exposure / {plan.n_patterns})"
            )


def transmission(
    plan: AperturePlan,
    u,
    v,
    t,
    masks: np.ndarray | None = None,
    contrast: float | None = None,
    switch_ms: float | None = None,
) -> np.ndarray:
    """A(u, v, t) of ``plan`` at lens points (u, v) (mm, the plugin's local frame) and times
    t (ms on the design's shutter clock: one per point, or one for all), float32.

    0 outside the exposure and in closed patterns; inside an open pattern, 1 in the opening
    (a disc about the pattern's centre at t, or a bitmap's value at its LCoS pixel) and
    1 / ``contrast`` elsewhere on the lens (a finite-contrast LCoS's leakage, disc schedules).
    With ``switch_ms`` t_s > 0, in the first t_s of pattern k > 0's window (tau into it) the
    pixels turn linearly from pattern k - 1: A = (tau / t_s) A_k + (1 - tau / t_s) A_(k-1),
    the expectation of the plugin's draw of k - 1 with probability 1 - tau / t_s.
    """
    t = np.asarray(t, np.float64)  # one time (a moving scene's step) is computed once
    inside = (t >= plan.t_open) & (t < plan.t_close)
    tc = np.clip(t, plan.t_open, plan.t_close)
    k = plan.pattern_at(tc)
    shown = inside & plan.is_open[k]
    a = _pattern(plan, masks, u, v, k, tc, contrast)
    if switch_ms:
        f = np.clip((tc - plan.pattern_edges[k]) / switch_ms, 0.0, 1.0)
        old = np.broadcast_to((k > 0) & (f < 1.0), np.shape(a))
        if old.any():
            prev = _pattern(plan, masks, u, v, np.maximum(k - 1, 0), tc, contrast)
            a = np.where(old, f * a + (1.0 - f) * prev, a)
    return np.where(shown, a, 0.0).astype(np.float32)


def _pattern(plan: AperturePlan, masks, u, v, k, t, contrast) -> np.ndarray:
    """Pattern k's transmittance at lens points (u, v), time t (its disc's centre there)."""
    if plan.kind == "bitmap":
        return _bitmap(plan, masks, u, v, k)
    c = plan.centres_mm[k].copy()
    c[..., 0] += plan.aperture_quad * (np.asarray(t) - plan.t_mid) ** 2
    r2 = (u - c[..., 0]) ** 2 + (v - c[..., 1]) ** 2
    a = (r2 < plan.radius_mm**2).astype(np.float32)
    if contrast is not None:
        a = np.maximum(a, np.float32(1.0 / contrast))
    return a


def _bitmap(plan: AperturePlan, masks: np.ndarray, u, v, k) -> np.ndarray:
    """The bitmap's transmittance at each lens point: local x falls with the column, y with
    the row (:func:`~pacam_render.model.masks.pixel_centres_mm`)."""
    if masks is None:
        raise ParameterError("a bitmap schedule's transmission needs its masks")
    n, h, w = masks.shape
    k = np.broadcast_to(k, np.shape(u))
    pitch = plan.tables.pitch_mm
    col = np.floor(w / 2.0 - u / pitch).astype(np.int64)
    row = np.floor(h / 2.0 - v / pitch).astype(np.int64)
    ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    out = np.zeros(np.shape(u), np.float32)
    out[ok] = masks[k[ok], row[ok], col[ok]]
    return out


def design_aperture(plan, params: dict) -> AperturePlan:
    """A capture plan's :class:`~pacam_render.render.plan.AperturePlan`, as the plugin builds
    it from the same parameters (``params``: the plan's sensor parameters)."""
    return plan.aperture(params)
