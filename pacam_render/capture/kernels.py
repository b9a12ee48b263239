"""The kernels a capture's record describes: its analytic and speed-robust PSFs, registered to
the pinhole image, with the capture's diffraction where it includes it."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..model.camera import CameraDesign
from ..psf.analytic import design_psf
from ..psf.diffraction import DECONVOLUTION_MAX_LOST
from ..psf.exact_defocus import ray_kernel
from ..psf.robust import speed_robust_psf
from .record import CaptureRecord


class CapturePSF(NamedTuple):
    """A kernel to deblur with, where it came from, what its centre pixel stands for, and how
    its camera differs from the capture's (empty: the same design, or not recorded)."""

    kernel: np.ndarray
    file: Path | None
    origin: str
    t0_offset_px: float
    mismatch: tuple[str, ...] = ()


def named_psf(name: str, record: CaptureRecord) -> CapturePSF:
    """The kernel ``analytic`` (:func:`analytic_psf`) or ``robust`` (:func:`robust_psf`) of a
    capture's record, on the pinhole registration."""
    k = analytic_psf(record) if name == "analytic" else robust_psf(record)
    return CapturePSF(k, None, "pinhole", 0.0)


def capture_diffraction(record: CaptureRecord) -> dict | None:
    """The diffraction a capture includes, for its analytic kernels: ``wavelength_nm`` (the
    green channel's, or grey's), ``pixel_pitch_mm`` and ``psf``, the PSF its rays drew
    (``exact`` or ``fraunhofer``: geometric x Airy, as captures before the exact rays, a leaky
    LCoS's and bitmaps'); None when it has none (or an older capture, which had none)."""
    block = record.optics_error or {}
    info = block.get("diffraction") or {}
    included = (block.get("effects") or {}).get("diffraction", {}).get("included")
    if not included or "wavelengths_nm" not in info:
        return None
    waves = info["wavelengths_nm"]
    return {
        "wavelength_nm": float(waves[1] if len(waves) == 3 else waves[0]),
        "pixel_pitch_mm": info.get("pixel_pitch_mm"),
        "psf": info.get("ray_psf", "fraunhofer"),
    }


def _diffracted(k, record: CaptureRecord, cam, s, size, build, psf: str | None = None):
    """``k`` (speed s px/ms) with the capture's diffraction (:func:`capture_diffraction`), when
    it has one, as its rays drew it (:func:`~pacam_render.psf.exact_defocus.ray_kernel`):
    ``build(cam, f, shape)`` makes ``k``'s kernel on pixels f times finer, so that the pixel's
    box is counted once; without ``size``, the far rings' last 1 % are left out
    (``DECONVOLUTION_MAX_LOST``). ``psf`` overrides the record's kind of PSF."""
    d = capture_diffraction(record)
    if d is None or record.mode == "reference":
        return k

    wl, pitch = d["wavelength_nm"], d["pixel_pitch_mm"]
    lost = DECONVOLUTION_MAX_LOST if size is None else None
    kind = psf or d["psf"]
    return ray_kernel(build, cam, record.mode, s, "pinhole", wl, k.shape, pitch, lost, kind)


def analytic_psf(record: CaptureRecord, s: float = 0.0, size=None):
    """The analytic PSF of a recorded capture at speed s (px/ms), registered to the pinhole
    image as the ``reference`` capture and the scene are (``origin="pinhole"``); with the
    LCoS's leak, when the capture has a finite contrast (:func:`leaky_psf`), and the capture's
    diffraction, when it includes it (:func:`capture_diffraction`)."""

    cam = CameraDesign.from_inputs(record.camera)
    contrast = (record.sensor_params or {}).get("lcos_contrast")

    def build(c, f, fine):
        return leaky_psf(c, record.mode, s * f, fine, contrast)

    if contrast is None:
        k = design_psf(cam, record.mode, s, size, origin="pinhole")
    else:
        k = leaky_psf(cam, record.mode, s, size, contrast)
    return _diffracted(k, record, cam, s, size, build)


def leaky_psf(cam, mode: str, s: float, size, contrast: float | None):
    """The kernel of ``cam`` in ``mode`` when the LCoS's "off" pixels pass 1/C of the light:
    (1 - 1/C) A_c K_coded + (1/C) K_full over their sum, with A_c the opening's share of the
    lens and K_full the whole lens's kernel over the same exposure, focus and motion (the rays'
    transmittance: 1 in the opening, 1/C on the rest of the lens). A disc schedule only; the
    leak's own diffraction is taken as the opening's (its light is 1/C)."""

    k = design_psf(cam, mode, s, size, origin="pinhole")
    if contrast is None or cam.pattern_masks is not None or cam.R_mm >= cam.R_max_mm:
        return k
    full = cam.with_(pattern_centres_mm=((0.0, 0.0),) * cam.n_patterns, R_mm=cam.R_max_mm,
                     quoted_a_i_px_per_ms2=None)  # fmt: skip
    if size is None:  # the whole lens's disc is the wider: both on its window
        kf = design_psf(full, mode, s, None, origin="pinhole")
        shape = tuple(max(a, b) for a, b in zip(k.shape, kf.shape))
        k = design_psf(cam, mode, s, shape, origin="pinhole")
    else:
        shape = k.shape
    kf = design_psf(full, mode, s, shape, origin="pinhole")
    c = float(contrast)
    w_coded = (1.0 - 1.0 / c) * (cam.R_mm / cam.R_max_mm) ** 2
    out = w_coded * k + kf / c
    return out / out.sum()


def robust_psf(record: CaptureRecord, size=None):
    """The speed-robust analytic PSF of a recorded capture: averaged over the design's invariant
    range (:func:`~pacam_render.psf.robust.speed_robust_psf`), registered as :func:`analytic_psf`,
    with the capture's diffraction as the geometric kernel convolved with the Airy pattern
    (the speed average of the exact defocused kernels is not built: for a capture whose rays
    drew the exact PSF this kernel is that model's, L1 0.25 from it at r = 2 px).
    """

    cam = CameraDesign.from_inputs(record.camera)
    k = speed_robust_psf(cam, record.mode, size=size, origin="pinhole")

    def build(c, f, fine):
        return speed_robust_psf(c, record.mode, size=fine, origin="pinhole")

    return _diffracted(k, record, cam, 0.0, size, build, psf="fraunhofer")
