"""Where in a frame the convolution model can be right: regions from the ground-truth layers.

Near an *occluding edge* (two objects, or one object's depth jumping) a ray tracer mixes the
two sides' light through the moving aperture and over the exposure, which no per-surface
convolution does. How far that reaches is the PSF's own reach: a band of that width around
each edge. Every pixel of the window gets one region (:data:`REGIONS`, in order of priority):

``frame``
    Its PSF, or a neighbour's, reads beyond the rendered truth window: not scored.
``moving_edge_band``
    A moving object's pixel within the moving PSFs' reach of any edge.
``background_near_moving``
    A still pixel within the moving PSFs' reach of a moving object's edge: the background that
    the object covers or uncovers during the exposure.
``still_edge_band``
    A still pixel within the still PSFs' reach of an edge between still surfaces (the moving
    aperture's parallax alone).
``moving_interior`` / ``still_interior``
    Everything else: farther from every edge than any PSF reaches.
"""

from __future__ import annotations

import numpy as np

REGIONS = (
    "frame",
    "still_interior",
    "still_edge_band",
    "background_near_moving",
    "moving_edge_band",
    "moving_interior",
)
"""Region names; a region map holds their indices."""
EDGE_JUMP_PX = 0.5
"""A depth step inside one object is an edge when it moves the aperture's images (beta R_max)
by more than this, px."""


def edges(ids: np.ndarray, beta_r_px: np.ndarray, velocity: np.ndarray):
    """Pixels on an occluding edge (4-neighbours of another object, or across a depth step).

    Returns
    -------
    moving, still : ndarray of bool
        Edge pixels where either side moves, and where both are still.
    """
    moving_px = np.any(velocity != 0.0, axis=-1)
    on_moving = np.zeros(ids.shape, bool)
    on_still = np.zeros(ids.shape, bool)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        a, b = tuple(a), tuple(b)
        jump = (ids[a] != ids[b]) | (np.abs(beta_r_px[a] - beta_r_px[b]) > EDGE_JUMP_PX)
        mov = jump & (moving_px[a] | moving_px[b])
        sti = jump & ~mov
        for mask, out in ((mov, on_moving), (sti, on_still)):
            out[a] |= mask
            out[b] |= mask
    return on_moving, on_still


def region_map(
    ids: np.ndarray,
    beta_r_px: np.ndarray,
    velocity: np.ndarray,
    reach_moving_px: float,
    reach_still_px: float,
    reach_max_px: float,
) -> np.ndarray:
    """The region (index into :data:`REGIONS`) of every pixel of a truth window.

    Parameters
    ----------
    ids, beta_r_px, velocity : ndarray
        Object ids, beta R_max (px) and image velocity (px/ms) of the window's pixels.
    reach_moving_px, reach_still_px : float
        The band widths: how far the moving and the still surfaces' PSFs reach, px.
    reach_max_px : float
        Pixels nearer the window's border than this are ``frame``.
    """
    from scipy.ndimage import distance_transform_edt

    on_moving, on_still = edges(ids, beta_r_px, velocity)
    d_moving = _distance(on_moving, distance_transform_edt)
    d_any = _distance(on_moving | on_still, distance_transform_edt)
    moving_px = np.any(velocity != 0.0, axis=-1)
    out = np.full(ids.shape, REGIONS.index("still_interior"), np.int8)
    out[~moving_px & (d_any <= reach_still_px)] = REGIONS.index("still_edge_band")
    out[~moving_px & (d_moving <= reach_moving_px)] = REGIONS.index("background_near_moving")
    out[moving_px] = REGIONS.index("moving_interior")
    out[moving_px & (d_any <= reach_moving_px)] = REGIONS.index("moving_edge_band")
    h, w = ids.shape
    i, j = np.ogrid[:h, :w]
    border = np.minimum(np.minimum(i, h - 1 - i), np.minimum(j, w - 1 - j))
    out[border < reach_max_px] = REGIONS.index("frame")
    return out


def moving_edge_distance(ids, beta_r_px, velocity) -> np.ndarray:
    """Distance of every pixel to the nearest edge of a moving object, px: negative on moving
    pixels, positive on still ones (inf where no edge is in view)."""
    from scipy.ndimage import distance_transform_edt

    on_moving, _ = edges(ids, beta_r_px, velocity)
    d = _distance(on_moving, distance_transform_edt)
    return np.where(np.any(velocity != 0.0, axis=-1), -d, d)


def _distance(edge: np.ndarray, edt) -> np.ndarray:
    """Distance of every pixel to the nearest edge pixel, px (inf without edges)."""
    if not edge.any():
        return np.full(edge.shape, np.inf)
    return edt(~edge)
