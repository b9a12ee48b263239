"""Scores of a restored image against a capture's ground truth, per object.

A motion-invariant PSF moves each object by its own -s^2 / (2 a_i) px along the aperture's
path (horizontal here), so each moving object is compared at its own best whole-pixel
horizontal shift within +-``max_shift_px``; still pixels are compared where they are. Columns
within ``max_shift_px`` of the left and right edges are left out, so every shift exists.
"""

from __future__ import annotations

import json

import numpy as np

from ..restore.metrics import aligned_psnr, shift_search_px, ssim

MIN_OBJECT_PX = 16
"""An object with fewer visible pixels is not scored on its own (too few to mean anything)."""


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


def moving_object_se(est, layers: dict, objects: dict, moving: set[str], max_shift_px: int):
    """Each moving object's smallest sum of squared errors over horizontal shifts and its
    count of values (pixels x channels), for objects of at least :data:`MIN_OBJECT_PX`
    visible pixels away from the shift search's edge columns.

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
            out[name] = (best_shift_se(est, truth, mask, m)[0], int(mask.sum()) * channels)
    return out


def psnr_moving_db(est, layers: dict, objects: dict, moving: set[str], max_shift_px: int) -> float:
    """:func:`score`'s ``psnr_moving_db`` alone (no SSIM, no whole frame): every moving
    object's pixels, each at its own best shift (:func:`moving_object_se`); nan without any."""
    per = moving_object_se(est, layers, objects, moving, max_shift_px).values()
    n = sum(v[1] for v in per)
    return _psnr_from_mse(sum(v[0] for v in per) / n) if n else float("nan")


def score(
    est, layers: dict, objects: dict, moving: set[str], max_shift_px: int, edge_px: int = 0
) -> dict:
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

    Returns
    -------
    dict
        ``psnr_db`` (whole frame, one best shift), ``ssim`` (whole frame), ``psnr_moving_db``
        (the moving objects' pixels, each at its best shift; nan without any),
        ``psnr_static_db`` (every other pixel, unshifted), ``psnr_moving_interior_db`` (the
        moving objects' interiors, each at its best shift: no occlusion there) and
        ``psnr_by_object`` (JSON: shape id to [PSNR dB, best shift px]), all with a peak of 1.
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
        se, shift = best_shift_se(est, truth, mask, m if name in moving else 0)
        n = mask.sum() * channels
        per[name] = [round(_psnr_from_mse(se / n), 3), shift]
        if name in moving:
            se_moving, n_moving = se_moving + se, n_moving + n
            inner = _interior(mask, edge_px)
            if inner.sum() >= MIN_OBJECT_PX:
                se_i, _ = best_shift_se(est, truth, inner, m)
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
    return score(est, layers, objects, moving, _shift_search(record), edge)


def frame_psnr_db(est, layers: dict, record) -> float:
    """:func:`score_capture`'s ``psnr_db`` alone (the whole frame at its best shift), for an
    image scored only for comparison (a deconvolver's blurred input)."""
    return aligned_psnr(est, layers["sharp"], FRAME, _shift_search(record))


FRAME = (0.0, 1.0, 0.0, 1.0)
"""The whole frame, as :func:`~pacam_render.restore.metrics.aligned_psnr` crops."""


def _shift_search(record) -> int:
    """The capture's alignment search, px (:func:`shift_search_px` of its sensor's width)."""
    return shift_search_px(record.spec.get("width") or record.camera.get("width_px"))
