"""A capture deblurred and scored as ``pacam deconvolve`` does it, in one call.

:func:`restore_capture` is the command's work without its files: the layer to deblur (the
sensor's ``noisy`` when there is one), what the deconvolver is told by default (the sensor's
noise and the render's own Monte Carlo sigma, flat-fielded by the relative illumination,
:func:`~pacam_render.restore.capture_deblur.deblur_input`), the deconvolution, the estimate
registered to the pinhole image, and the score against ``sharp`` that a study gives
(:func:`~pacam_render.restore.object_score.score_capture`). ``pacam deconvolve`` calls it, so a
Python user's figures are the command's (a bare :func:`~pacam_render.restore.deconvolve.deconvolve`
with one sigma is not: it skips the flat field and the render's noise).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field

import numpy as np

from ..capture.kernels import CapturePSF, named_psf
from ..capture.record import CaptureRecord
from ..errors import ParameterError
from ..limits import note
from ..psf.origin import to_pinhole
from .capture_deblur import deblur_input
from .capture_noise import check_noise_sigma, deblur_layer
from .deconvolve import deconvolve, nonnegative_for, require_method
from .object_score import frame_psnr_db, score_capture

TRUTH = frozenset({"sharp", "object_id", "velocity"})
"""The layers a score needs."""


@dataclass(frozen=True)
class Restoration:
    """A capture deblurred (:func:`restore_capture`).

    Attributes
    ----------
    estimate : numpy.ndarray
        The deblurred layer, in the layer's units, registered to the pinhole image.
    layer, method : str
        The layer deblurred and the method.
    psf : CapturePSF
        The kernel, where it came from and its origin.
    noise : dict
        The noise told the deconvolver and its ``source``.
    how : str or None
        How that noise was made up, in words.
    seconds : float
        The deconvolution's seconds.
    score : dict
        ``psnr_db``, ``ssim``, ``psnr_moving_db``, ``psnr_static_db`` and ``psnr_by_object``
        against ``sharp`` (white = 1), as ``pacam deconvolve`` prints them; empty without the
        truth layers or for a layer that is not the image.
    """

    estimate: np.ndarray
    layer: str
    method: str
    psf: CapturePSF
    noise: dict
    how: str | None
    seconds: float
    score: dict = field(default_factory=dict)


def restore_capture(
    capture,
    record: CaptureRecord | None = None,
    psf: CapturePSF | str = "analytic",
    method: str = "hl",
    layer: str | None = None,
    colour: str | None = None,
    noise_sigma: float | None = None,
    model_sigma: float | None = None,
    before=None,
) -> Restoration:
    """Deblur a capture's layer and score it, as ``pacam deconvolve`` does (module docstring).

    Parameters
    ----------
    capture : Capture or dict
        A :class:`~pacam_render.capture.result.Capture` (as
        :func:`~pacam_render.exposure.direct.render_capture` returns it, with its sensor
        layers), or a capture's layers by name (``capture``, ``noisy``, the truth layers, ...)
        as :func:`~pacam_render.io.exr.read_exr` reads them.
    record : CaptureRecord, optional
        The capture's record (its noise, light factor, relative illumination, camera); a
        Capture's own by default.
    psf : CapturePSF or str, optional
        The kernel: ``analytic`` (default) or ``robust`` from the record, or a loaded one
        (:func:`~pacam_render.exposure.deblur_psf.load_capture_psf`).
    method : str, optional
        A deconvolution method (:data:`~pacam_render.restore.deconvolve.METHODS`); default
        ``hl``, the command's.
    layer : str, optional
        The layer to deblur (default ``noisy`` when there is one, else ``capture``).
    colour : str, optional
        hl/tv: one prior on each gradient's colour vector (``joint``) or one per channel.
    noise_sigma : float, optional
        The whole noise std told the deconvolver, in the layer's units (default: the sensor's
        and the render's, from the record).
    model_sigma : float, optional
        The capture's departure from the deconvolver's model, white = 1, added in quadrature.
    before : callable, optional
        Called with the deconvolver's options once they are known, before it runs (``pacam
        deconvolve`` checks its memory there).

    Returns
    -------
    Restoration
        The estimate, the noise told, the seconds and the score.

    Raises
    ------
    ParameterError
        If the method, layer, noise or kernel is refused.
    """
    require_method(method)
    layers = capture_layers(capture) if hasattr(capture, "extra_layers") else dict(capture)
    record = capture.record if record is None and hasattr(capture, "record") else record
    layer = deblur_layer(list(layers), layer)
    image = np.asarray(layers[layer])
    check_noise_sigma(noise_sigma, image)
    if isinstance(psf, str):  # a kernel file is loaded by its reader (exposure.deblur_psf)
        if record is None:
            raise ParameterError(f"`psf` {psf} needs the capture's record")
        psf = named_psf(check_psf_name(psf), record)
    d = deblur_input({**layers, layer: image}, layer, record, method, colour, noise_sigma,
                     model_sigma)  # fmt: skip
    if before is not None:
        before(d.kw)
    data, clipped = nonnegative_for(method, d.image)
    if clipped:
        note(f"rl needs non-negative data: {clipped} value(s) of layer {layer} below 0 (read "
             "noise) clipped to 0")  # fmt: skip
    start = time.perf_counter()
    est = deconvolve(data, psf.kernel, method, **d.kw)
    est = to_pinhole(est, psf.origin, psf.t0_offset_px)  # the capture's registration
    seconds = time.perf_counter() - start
    score = score_restoration(est, layers, layer, record)
    if score:
        _note_worse_than_input(score["psnr_db"], d.image, layers, layer, record)
    return Restoration(est, layer, method, psf, d.noise, d.how, seconds, score)


def check_psf_name(psf: str) -> str:
    """``psf`` given by name: ``analytic`` or ``robust`` (a file is loaded first)."""
    if psf not in ("analytic", "robust"):
        raise ParameterError(
            f"`psf` {psf!r}: give analytic or robust, or a kernel loaded with "
            "pacam_render.exposure.deblur_psf.load_capture_psf"
        )
    return psf


def _note_worse_than_input(psnr_db: float, image, layers: dict, layer: str, record) -> None:
    """A note when the estimate scores below the blurred image it was deblurred from. That
    image is scored as the estimate is (:func:`score_restoration`'s whole-frame PSNR, divided
    by the light factor, best shift): it is the deconvolver's own input (flat-fielded like the
    estimate), and a capture is already on the pinhole registration the estimate is moved to."""
    blurred = frame_psnr_db(np.asarray(image) / record.light_factor, layers, record)
    if psnr_db < blurred:
        note(
            f"the deblurred estimate scores {psnr_db:.2f} dB against sharp, below the blurred "
            f"input's own {blurred:.2f} dB (layer {layer}, scored alike): deblurring made it "
            "worse; check the kernel (`psf`), the noise told (noise_sigma) and the `method`"
        )


def score_restoration(est, layers: dict, layer: str, record) -> dict:
    """PSNR and SSIM against ``sharp`` as a study scores
    (:func:`~pacam_render.restore.object_score.score_capture`), on the white scale; empty
    without the truth layers or for a layer that is not the image."""
    if record is None or layer not in ("capture", "noisy") or not TRUTH <= set(layers):
        return {}
    if record.light_factor <= 0 or est.shape != np.shape(layers["sharp"]):
        return {}
    if not np.all(np.isfinite(layers["sharp"])):
        note("the capture's sharp layer holds NaN or inf: no score")
        return {}
    out = score_capture(est / record.light_factor, layers, record)
    return {**out, "psnr_by_object": json.loads(out["psnr_by_object"])}


def capture_layers(cap) -> dict:
    """A :class:`~pacam_render.capture.result.Capture`'s layers by the names its EXR gives
    them (``capture``, then the extra layers: ``noisy``, the truth, ...)."""
    return {"capture": cap.image, **cap.extra_layers}
