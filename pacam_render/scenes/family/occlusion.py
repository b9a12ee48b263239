"""Occlusion events of a family scene: which object passes in front of which, inside the
window, during the exposure.

Each object's image footprint is the projection of a fronto-parallel cross-section through its
centre (a disc for a sphere, a rectangle otherwise). That section lies inside the object, so
where two footprints overlap, the nearer object truly hides the farther one: the footprint is an
inner bound of the silhouette, and an event is never claimed where there is none. Overlaps are
counted at the window's pixel centres, at :data:`TIME_STEP_MS` steps over [-T, T].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TIME_STEP_MS = 0.25
"""Time step of the overlap test, ms."""
MIN_OVERLAP_PX = 16
"""Pixel centres an overlap must hold, at every step of a run, for the event to count as a
guaranteed occlusion (``passes``)."""
MIN_OCCLUSION_MS = 2.0
"""How long such a run must last, ms."""
MIN_RELATIVE_SHIFT_PX = 1.0
"""How far, px, the two objects must move relative to each other over the exposure: an
occluding edge that sweeps across the one behind, not a still overlap."""


@dataclass(frozen=True)
class Footprint:
    """An object's image footprint at t = 0 and its image velocity (px, px/ms)."""

    object_id: str
    depth_mm: float
    kind: str  # "disc" or "rect"
    centre_px: tuple[float, float]
    half_px: tuple[float, float]  # half width and height (the radius twice for a disc)
    velocity_px_per_ms: tuple[float, float]

    def centre_at(self, t_ms: np.ndarray) -> np.ndarray:
        """(len(t), 2) image centres at times ``t_ms``."""
        c, v = np.asarray(self.centre_px), np.asarray(self.velocity_px_per_ms)
        return c + np.asarray(t_ms, float)[:, None] * v

    def inside(self, u: np.ndarray, v: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """Which points (u, v) lie in the footprint centred at ``centre``."""
        du, dv = u - centre[0], v - centre[1]
        if self.kind == "disc":
            return du**2 + dv**2 <= self.half_px[0] ** 2
        return (np.abs(du) <= self.half_px[0]) & (np.abs(dv) <= self.half_px[1])


def _overlap_count(a: Footprint, b: Footprint, ca, cb, window) -> tuple[int, tuple | None]:
    """Pixel centres of ``window`` inside both footprints (centred at ca, cb), and their
    bounding box (x0, y0, x1, y1), end exclusive, or None."""
    x, y, w, h = window
    lo = np.maximum.reduce([ca - a.half_px, cb - b.half_px, np.array([x, y], float)])
    hi = np.minimum.reduce([ca + a.half_px, cb + b.half_px, np.array([x + w, y + h], float)])
    k0 = np.ceil(lo - 0.5).astype(int)  # pixel k has its centre at k + 0.5
    k1 = np.floor(hi - 0.5).astype(int)
    if np.any(k1 < k0):
        return 0, None
    u = np.arange(k0[0], k1[0] + 1) + 0.5
    v = np.arange(k0[1], k1[1] + 1) + 0.5
    uu, vv = np.meshgrid(u, v)
    both = a.inside(uu, vv, ca) & b.inside(uu, vv, cb)
    n = int(both.sum())
    if n == 0:
        return 0, None
    cols, rows = np.flatnonzero(both.any(0)), np.flatnonzero(both.any(1))
    box = (int(k0[0] + cols[0]), int(k0[1] + rows[0]), int(k0[0] + cols[-1] + 1))
    return n, (*box, int(k0[1] + rows[-1] + 1))


def _longest_run(flags: np.ndarray) -> int:
    """Length of the longest run of True."""
    best = run = 0
    for f in flags:
        run = run + 1 if f else 0
        best = max(best, run)
    return best


def pair_event(front: Footprint, behind: Footprint, window, T_ms: float) -> dict | None:
    """The event of ``front`` (nearer) over ``behind`` inside ``window`` during [-T, T], or None
    if their footprints never overlap there."""
    n_steps = int(round(2 * T_ms / TIME_STEP_MS))
    t = np.linspace(-T_ms, T_ms, n_steps + 1)
    ca, cb = front.centre_at(t), behind.centre_at(t)
    counts, boxes = np.zeros(len(t), int), []
    for i in range(len(t)):
        counts[i], box = _overlap_count(front, behind, ca[i], cb[i], window)
        if box is not None:
            boxes.append(box)
    if not boxes:
        return None
    hit = np.flatnonzero(counts > 0)
    rel = np.subtract(front.velocity_px_per_ms, behind.velocity_px_per_ms)
    rel_speed = float(np.hypot(*rel))
    run_steps = _longest_run(counts >= MIN_OVERLAP_PX)
    b = np.array(boxes)
    passes = (run_steps - 1) * TIME_STEP_MS >= MIN_OCCLUSION_MS and (
        rel_speed * 2 * T_ms >= MIN_RELATIVE_SHIFT_PX
    )
    return {
        "front": front.object_id,
        "behind": behind.object_id,
        "first_ms": float(t[hit[0]]),
        "last_ms": float(t[hit[-1]]),
        "region_px": [
            int(b[:, 0].min()),
            int(b[:, 1].min()),
            int(b[:, 2].max()),
            int(b[:, 3].max()),
        ],
        "max_overlap_px": int(counts.max()),
        "relative_speed_px_per_ms": rel_speed,
        "passes": bool(passes),
    }


def occlusion_events(footprints: list[Footprint], window, T_ms: float) -> list[dict]:
    """Every pair's event (:func:`pair_event`), nearer object first, in the order of the ids.

    ``region_px`` is the bounding box (x0, y0, x1, y1; sensor px, end exclusive) of the overlap
    over the event; ``first_ms``/``last_ms`` the first and last step with an overlap;
    ``passes`` whether it is a guaranteed occlusion (:data:`MIN_OVERLAP_PX`,
    :data:`MIN_OCCLUSION_MS`, :data:`MIN_RELATIVE_SHIFT_PX`).
    """
    events = []
    for i, a in enumerate(footprints):
        for b in footprints[i + 1 :]:
            front, behind = (a, b) if a.depth_mm < b.depth_mm else (b, a)
            event = pair_event(front, behind, window, T_ms)
            if event is not None:
                events.append(event)
    return events
