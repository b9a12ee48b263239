"""Scores of a restored image against a capture's ground truth, per object.

A motion-invariant PSF moves each object by its own -s^2 / (2 a_i) px along the aperture's
path (horizontal here), so each moving object is compared at its own best whole-pixel
horizontal shift; still pixels are compared where they are. The search is bounded by the
physics (:func:`physical_shift_px`): within what the object's speed can move its restored
image, plus a slack, so that a textured object cannot lock onto its texture's period (the
prototype's box aligned at 15 px for one seed and 0 px for another, its checker's period being
about 17 px). Columns within ``max_shift_px`` of the left and right edges are left out, so
every shift exists.
"""

from __future__ import annotations

import json

import numpy as np

from ..model.modes import mode as mode_of
from ..restore.metrics import aligned_psnr, shift_search_px, ssim

MIN_OBJECT_PX = 16
"""An object with fewer visible pixels is not scored on its own (too few to mean anything)."""
SHIFT_SLACK_PX = 2
"""Added to the physical shift bound beside the defocus radius: whole-pixel alignment and the
kernel's asymmetry (the bound's slack is SHIFT_SLACK_PX + ceil(r_px))."""


def physical_shift_px(speed_px_per_ms: float, mode: str, optics: dict, max_shift_px: int) -> int:
    """How far an object at image speed ``speed_px_per_ms`` can appear shifted after a
    restoration with the still PSF in a ``mode`` capture, px (at most ``max_shift_px``).

    The object's path relative to the aperture's image is s t + p(t), t in [-T, T], where
    p(t) is the image shift of the opening shown at t (``beta_px_per_mm`` times its centre's
    x, the record's ``pattern_centres_xy_mm``; the parabola a_i t^2 / 2, Eq. 18).

    * The parabola inside the invariant range |s| <= |a_i| T (``coded`` modes of a parabolic
      schedule, ``levin``): its PSF is the still one shifted by the vertex, s^2 / (2 |a_i|).
    * Any other moving opening (the parabola beyond its range, designed centres, bitmaps):
      the PSF is not the still one's shifted, and the restored object may sit anywhere along
      the path: its reach, |s| T + the openings' image span (the parabola's |a_i| T^2 / 2; the
      path's end alone cost the prototype's near train 0.8 dB on a fresh render).
    * A still opening (``normal``, ``short``, the pinhole): symmetric about t = 0, no shift;
      the flutter shutter's code is not symmetric: |s| T.

    Each bound adds the slack :data:`SHIFT_SLACK_PX` + ceil(``r_px``).
    """
    s = abs(float(speed_px_per_ms))
    schedule = mode_of(mode).schedule
    slack = SHIFT_SLACK_PX + int(np.ceil(float(optics.get("r_px", 0.0))))
    a = abs(float(optics.get("a_i_px_per_ms2") or 0.0))
    T = float(optics.get("T_ms") or 0.0)
    kind = optics.get("schedule_kind", "parabolic")
    if schedule in (None, "static"):
        d = 0.0
    elif T <= 0:
        return int(max_shift_px)  # no exposure known: no bound
    elif schedule == "camera_parabolic" or (schedule == "parabolic" and kind == "parabolic"):
        d = s * s / (2 * a) if a > 0 and s <= a * T else s * T + a * T * T / 2
    elif schedule == "flutter":
        d = s * T
    else:  # designed centres or bitmaps
        d = s * T + _opening_span_px(optics)
    return min(int(max_shift_px), int(np.ceil(d - 1e-9)) + slack)


def _opening_span_px(optics: dict) -> float:
    """The image span of the schedule's openings, px: |beta| x (largest - smallest centre x),
    over its open patterns (a black pattern's centre is NaN)."""
    pairs = optics.get("pattern_centres_xy_mm") or [[0.0, 0.0]]
    # a black pattern's centre is NaN, or None once the record went through JSON
    x = np.array([np.nan if c is None or c[0] is None else c[0] for c in pairs], float)
    x = x[np.isfinite(x)]
    beta = abs(float(optics.get("beta_px_per_mm") or 0.0))
    return beta * float(np.ptp(x)) if x.size else 0.0


def shift_bounds(layers: dict, objects: dict, moving: set[str], record, max_shift_px: int):
    """Each moving object's :func:`physical_shift_px` at its fastest pixel's horizontal speed
    (the ``velocity`` layer, px/ms), in the capture ``record``'s mode and optics."""
    vx, ids = np.abs(layers["velocity"][..., 0]), layers["object_id"]
    out = {}
    for key, name in objects.items():
        pix = ids == int(key)
        if name in moving and pix.any():
            speed = float(vx[pix].max())
            out[name] = physical_shift_px(speed, record.mode, record.optics or {}, max_shift_px)
    return out


def _psnr_from_mse(mse: float) -> float:
    return float("inf") if mse <= 0 else float(-10.0 * np.log10(mse))


def best_shift_se(est, truth, mask, max_shift_px: int) -> tuple[float, int]:
    """Smallest sum of squared errors over horizontal shifts d of ``est`` on ``mask``.

    Returns
    -------
    se : float
        min over d in [-max_shift_px, max_shift_px] of sum (est[r, c + d] - truth[r, c])^2
        over the mask's pixels (r, c) and channels.
    shift : int
        The best d, px.
    """
    rows, cols = np.nonzero(mask)
    target = truth[rows, cols]
    errs = [
        float(np.sum((est[rows, cols + d] - target) ** 2))
        for d in range(-max_shift_px, max_shift_px + 1)
    ]
    k = int(np.argmin(errs))
    return errs[k], k - max_shift_px


def moving_object_se(
    est, layers: dict, objects: dict, moving: set[str], max_shift_px: int, bounds=None
):
    """Each moving object's smallest sum of squared errors over horizontal shifts (within
    its ``bounds``, :func:`shift_bounds`, else ``max_shift_px``) and its count of values
    (pixels x channels), for objects of at least :data:`MIN_OBJECT_PX` visible pixels away
    from the shift search's edge columns.

    Returns
    -------
    dict
        Shape id to (se, n).
    """
    truth, ids = layers["sharp"], layers["object_id"]
    channels = 1 if truth.ndim == 2 else truth.shape[2]
    m = int(max_shift_px)
    valid = np.zeros(ids.shape, bool)
    valid[:, m : ids.shape[1] - m] = True
    out = {}
    for key, name in objects.items():
        mask = valid & (ids == int(key))
        if name in moving and mask.sum() >= MIN_OBJECT_PX:
            b = (bounds or {}).get(name, m)
            out[name] = (best_shift_se(est, truth, mask, b)[0], int(mask.sum()) * channels)
    return out


def psnr_moving_db(est, layers: dict, objects: dict, moving: set[str], max_shift_px: int) -> float:
    """:func:`score`'s ``psnr_moving_db`` alone (no SSIM, no whole frame): every moving
    object's pixels, each at its own best shift (:func:`moving_object_se`); nan without any."""
    per = moving_object_se(est, layers, objects, moving, max_shift_px).values()
    n = sum(v[1] for v in per)
    return _psnr_from_mse(sum(v[0] for v in per) / n) if n else float("nan")


def score(
    est, layers: dict, objects: dict, moving: set[str], max_shift_px: int, edge_px: int = 0,
    bounds: dict | None = None,
) -> dict:  # fmt: skip
    """PSNR and SSIM of ``est`` against the ``sharp`` layer, overall and per object.

    Parameters
    ----------
    est : ndarray
        (H, W, 3) estimate, white = 1; (H, W) for a grey capture.
    layers : dict
        The capture's ground truth: ``sharp`` (the estimate's shape) and ``object_id``.
    objects : dict
        The legend, object id (str) to shape id.
    moving : set of str
        Shape ids that move.
    max_shift_px : int
        The alignment search, px.
    edge_px : int, optional
        How far the blur reaches from a moving object's outline, px: its interior, where no
        background is mixed in, is its mask eroded by this much horizontally.
    bounds : dict, optional
        Shape id to its shift search, px (:func:`shift_bounds`); ``max_shift_px`` otherwise.

    Returns
    -------
    dict
        ``psnr_db`` (whole frame, one best shift), ``ssim`` (whole frame), ``psnr_moving_db``
        (the moving objects' pixels, each at its best shift; nan without any),
        ``psnr_static_db`` (every other pixel, unshifted), ``psnr_moving_interior_db`` (the
        moving objects' interiors, each at its best shift: no occlusion there) and
        ``psnr_by_object`` (JSON: shape id to [PSNR dB, best shift px]), all with a peak of 1,
        and ``shift_bound_px`` (JSON: each moving object's shift search, px).
    """
    truth, ids = layers["sharp"], layers["object_id"]
    channels = 1 if truth.ndim == 2 else truth.shape[2]  # a grey capture's sharp is (H, W)
    m = int(max_shift_px)
    valid = np.zeros(ids.shape, bool)
    valid[:, m : ids.shape[1] - m] = True
    per, se_moving, n_moving, se_in, n_in = {}, 0.0, 0, 0.0, 0
    moving_mask = np.zeros(ids.shape, bool)
    for key, name in objects.items():
        mask = valid & (ids == int(key))
        if name in moving:
            moving_mask |= mask
        if mask.sum() < MIN_OBJECT_PX:
            continue
        bound = (bounds or {}).get(name, m) if name in moving else 0
        se, shift = best_shift_se(est, truth, mask, bound)
        n = mask.sum() * channels
        per[name] = [round(_psnr_from_mse(se / n), 3), shift]
        if name in moving:
            se_moving, n_moving = se_moving + se, n_moving + n
            inner = _interior(mask, edge_px)
            if inner.sum() >= MIN_OBJECT_PX:
                se_i, _ = best_shift_se(est, truth, inner, bound)
                se_in, n_in = se_in + se_i, n_in + inner.sum() * channels
    still = valid & ~moving_mask
    se_still, _ = best_shift_se(est, truth, still, 0)
    return {
        "psnr_db": aligned_psnr(est, truth, FRAME, m),
        "ssim": ssim(est, truth),
        "psnr_moving_db": _psnr_from_mse(se_moving / n_moving) if n_moving else float("nan"),
        "psnr_static_db": _psnr_from_mse(se_still / max(1, still.sum() * channels)),
        "psnr_moving_interior_db": _psnr_from_mse(se_in / n_in) if n_in else float("nan"),
        "psnr_by_object": json.dumps(per, sort_keys=True),
        "shift_bound_px": json.dumps(
            {k: (bounds or {}).get(k, m) for k in sorted(moving & set(per))}
        ),
    }


def _interior(mask: np.ndarray, edge_px: int) -> np.ndarray:
    """``mask`` less everything within ``edge_px`` of its outline along a row."""
    from scipy.ndimage import binary_erosion

    if edge_px <= 0:
        return mask
    return binary_erosion(mask, structure=np.ones((1, 2 * int(edge_px) + 1), bool))


def edge_px(velocity: np.ndarray, exposure_ms: float, r_px: float) -> int:
    """How far a moving object's blur reaches past its t = 0 outline, px: its whole travel
    over the exposure (the fastest pixel's speed in ``velocity``, px/ms, times the exposure)
    and the defocus disc's diameter."""
    u = float(np.abs(velocity[..., 0]).max())
    return int(np.ceil(u * exposure_ms + 2 * r_px))


def moving_shapes(layers: dict, objects: dict) -> set[str]:
    """The shape ids of ``objects`` whose pixels move in the ``velocity`` layer."""
    speed = np.abs(layers["velocity"]).max(axis=-1)
    ids = layers["object_id"]
    return {name for key, name in objects.items() if np.any(speed[ids == int(key)] > 0)}


def score_capture(est, layers: dict, record) -> dict:
    """:func:`score` of ``est`` against a capture's ground truth, aligned as a study aligns.

    Parameters
    ----------
    est : ndarray
        (H, W, 3) estimate, or (H, W) for a grey capture, white = 1 (a capture's layer divided
        by its ``light_factor``).
    layers : dict
        The capture's ``sharp``, ``object_id`` and ``velocity`` layers.
    record : CaptureRecord
        The capture's record: its ``objects``, sensor width, exposure and defocus radius give
        the moving shapes, the shift search and the edge (:func:`edge_px`).

    Returns
    -------
    dict
        As :func:`score`.
    """

    objects = record.objects or {}
    r_px = record.optics.get("r_px", 0.0)
    edge = edge_px(layers["velocity"], record.exposure_ms, r_px)
    moving = moving_shapes(layers, objects)
    m = _shift_search(record)
    bounds = shift_bounds(layers, objects, moving, record, m)
    return score(est, layers, objects, moving, m, edge, bounds)


def frame_psnr_db(est, layers: dict, record) -> float:
    """:func:`score_capture`'s ``psnr_db`` alone (the whole frame at its best shift), for an
    image scored only for comparison (a deconvolver's blurred input)."""
    return aligned_psnr(est, layers["sharp"], FRAME, _shift_search(record))


FRAME = (0.0, 1.0, 0.0, 1.0)
"""The whole frame, as :func:`~pacam_render.restore.metrics.aligned_psnr` crops."""


def _shift_search(record) -> int:
    """The capture's alignment search, px (:func:`shift_search_px` of its sensor's width)."""
    return shift_search_px(record.spec.get("width") or record.camera.get("width_px"))
