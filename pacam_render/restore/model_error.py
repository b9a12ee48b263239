"""How far a capture departs from the convolution model that its deconvolver assumes.

A study restores a capture y (white = 1) with one kernel k: the mode's s = 0 PSF
(:func:`~.point.kernel`). If y = k * x + noise held with x the capture's ``sharp`` layer, the
residual y - k * sharp would hold only noise: the render's (``mc_sigma``) and the sharp
layer's, blurred by k. What is left over is the model error: the occlusions near moving edges,
the kernel's change with speed and depth, the 16 held patterns. Each moving object is
compared at its own best horizontal shift (a motion-invariant PSF moves it by -s^2 / 2 a_i,
which the deconvolver does not need to know), still pixels where they are, and a border as
wide as the kernel's reach and the shift search is left out (the window's edge sees light
from outside it that the sharp layer does not hold).

``model_sigma`` is the root mean square of that error over the window, with the noise taken
out: what the deconvolver is told on top of the sensor's and the render's noise. Modes
restored with a delta kernel (only denoised) have none: their data are what the denoiser
assumes.
"""

from __future__ import annotations

import numpy as np

from ..capture.kernels import analytic_psf
from ..model.illumination import flat_field
from .capture_score import STILL_KERNEL_MODES
from .flat_field import RI_LAYER
from .metrics import shift_search_px
from .object_score import best_shift_se


def convolve(image: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``image`` (H, W, C), or (H, W) grey, convolved with the odd-sized, centred kernel ``k``,
    same size, the image continued by reflection past its edges (as a natural scene goes on)."""
    from scipy.ndimage import convolve as nd_convolve

    if image.ndim == 2:
        return nd_convolve(image, k, mode="reflect")
    return np.stack(
        [nd_convolve(image[..., c], k, mode="reflect") for c in range(image.shape[2])], -1
    )


def residual_mse(y, sharp, k, ids, objects: dict, moving: set, max_shift_px: int) -> tuple:
    """Mean squared residual of ``y`` against ``k * sharp``, each moving object at its best
    shift, over the window less its border; and the mask of the pixels it covers.

    Returns
    -------
    mse : float
    mask : ndarray of bool
        (H, W): the pixels compared.
    """
    pred = convolve(sharp, k)
    m = int(max_shift_px)
    half = max(k.shape) // 2
    inner = np.zeros(ids.shape, bool)
    inner[half : ids.shape[0] - half, m + half : ids.shape[1] - m - half] = True
    se, done = 0.0, np.zeros(ids.shape, bool)
    for key, name in objects.items():
        mask = inner & (ids == int(key))
        if name in moving and mask.any():
            err, _ = best_shift_se(pred, y, mask, m)
            se, done = se + err, done | mask
    rest = inner & ~done
    if rest.any():
        se += best_shift_se(pred, y, rest, 0)[0]
    n = int(inner.sum()) * (1 if y.ndim == 2 else y.shape[2])
    return (se / n if n else 0.0), inner


def model_sigma(
    y, sharp, k, ids, objects: dict, moving: set, max_shift_px: int, y_var, sharp_var
) -> float:
    """The model error's sigma, white = 1 (see the module docstring).

    Parameters
    ----------
    y, sharp : ndarray
        (H, W, C), or (H, W) grey, the noiseless capture and its sharp layer, white = 1.
    k : ndarray
        The restoring kernel.
    ids, objects, moving : ndarray, dict, set
        The ``object_id`` layer, its legend, and the ids of the shapes that move.
    max_shift_px : int
        The alignment search, px.
    y_var, sharp_var : ndarray or float
        Per-pixel Monte Carlo variance of ``y`` and of ``sharp`` (white = 1).

    Returns
    -------
    float
        sqrt(max(0, mse - mean(y_var) - mean(sharp_var) sum(k^2))) over the compared pixels.
    """
    if k.size == 1:
        return 0.0
    mse, mask = residual_mse(y, sharp, k, ids, objects, moving, max_shift_px)
    noise = _mean_on(y_var, mask) + _mean_on(sharp_var, mask) * float(np.sum(k**2))
    return float(np.sqrt(max(0.0, mse - noise)))


def _mean_on(var, mask: np.ndarray) -> float:
    return float(np.mean(var[mask])) if np.ndim(var) else float(var)


def capture_model_sigma(layers: dict, record) -> float:
    """:func:`model_sigma` of a capture with its truth layers: its noiseless ``capture`` layer
    (white = 1, flat-fielded) against its analytic kernel at s = 0 (a delta for the modes
    that are only denoised) applied to ``sharp``. Measured on a calibration capture of a
    camera, it is the model error to tell the deconvolver for other captures of that camera
    (``pacam deconvolve --model-sigma-from``), without knowing their sharp images.
    """

    k = np.ones((1, 1)) if record.mode in STILL_KERNEL_MODES else analytic_psf(record)
    y = flat_field(np.asarray(layers["capture"], float) / record.light_factor, layers.get(RI_LAYER))
    ids = np.asarray(layers["object_id"]).astype(int)
    speed = np.abs(np.asarray(layers["velocity"])[..., 0])
    moving = {n for key, n in record.objects.items() if np.any(speed[ids == int(key)] > 0)}
    err = record.render_error
    mc = (err.mc_sigma_white_units if err else None) or 0.0
    sharp = (err.sharp_mc_sigma if err else None) or 0.0
    shift = shift_search_px(record.spec["width"])
    return model_sigma(y, layers["sharp"], k, ids, record.objects, moving, shift, mc**2, sharp**2)
