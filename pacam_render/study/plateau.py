"""What sets a deblurred capture's score: the same point restored three more ways.

A study's point is restored with the mode's kernel and told the sensor's and the render's
noise, and a model error where the study asks (:mod:`~pacam_render.restore.model_error`).
Three more restorations of the moving objects, each changing one thing, say what each part
costs:

* ``psnr_moving_no_model_sigma_db``: the deconvolver is not told the model error (sensor and
  render noise only): what measuring it buys;
* ``psnr_moving_floor_db``: it is told a fixed model floor of :data:`OLD_FLOOR` instead (the
  studies' constant before the model error was measured);
* ``psnr_moving_exact_model_db``: the capture replaced by what the convolution model predicts,
  ``k * sharp``, with the same sensor noise, restored exactly as the study restores it (the
  same sigma): the score if the data held no model error (no occlusion, no change of the
  kernel with speed or depth, no render noise), so the gap to ``psnr_moving_db`` is what the
  model's error costs at equal regularisation.
"""

from __future__ import annotations

import numpy as np

from ..restore.deconvolve import deconvolve
from ..restore.model_error import convolve

OLD_FLOOR = 0.02
"""The fixed model-error floor (white = 1) the studies told the deconvolver before issue 25."""
COLUMNS = (
    "psnr_moving_no_model_sigma_db",
    "psnr_moving_floor_db",
    "psnr_moving_exact_model_db",
)


def decompose(
    cap, k: np.ndarray, method: str, noisy: np.ndarray, parts, scorer, clean=None
) -> dict:
    """The three restorations of the module docstring, scored by ``scorer(est)`` (a dict with
    ``psnr_moving_db``); empty for a delta kernel or ``method`` none.

    Parameters
    ----------
    cap : Capture
        With its ``sharp`` layer; ``cap.image / light_factor`` is the noiseless capture.
    k : ndarray
        The restoring kernel.
    method : str
        The deconvolution method.
    noisy : ndarray
        The sensor's image, white = 1.
    parts : tuple of float
        (sensor, render, model) sigmas, white = 1.
    clean : ndarray, optional
        The noiseless capture as ``noisy`` is scaled (flat-fielded with it); default
        ``cap.image / light_factor``.
    """

    if k.size == 1 or method == "none":
        return {}
    sensor, render, model = parts
    if clean is None:
        clean = cap.image / cap.record.light_factor
    noise = noisy - clean  # this point's sensor noise
    total = float(np.sqrt(sensor**2 + render**2 + model**2))
    runs = {
        COLUMNS[0]: (noisy, np.hypot(sensor, render)),
        COLUMNS[1]: (noisy, float(np.sqrt(sensor**2 + render**2 + OLD_FLOOR**2))),
        COLUMNS[2]: (convolve(cap.extra_layers["sharp"], k) + noise, total),
    }
    out = {}
    for col, (y, sigma) in runs.items():
        est = deconvolve(y, k, method, noise_sigma=float(sigma))
        out[col] = scorer(est)["psnr_moving_db"]
    return out
