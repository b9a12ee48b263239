"""The kernels a capture's record describes: its analytic and speed-robust PSFs, registered to
the pinhole image, with the capture's diffraction where it includes it."""

from __future__ import annotations

from .record import CaptureRecord


def capture_diffraction(record: CaptureRecord) -> dict | None:
    """The diffraction a capture includes, for its analytic kernels: ``wavelength_nm`` (the
    green channel's, or grey's) and ``pixel_pitch_mm``; None when it has none (or an older
    capture, which had none)."""
    block = record.optics_error or {}
    info = block.get("diffraction") or {}
    included = (block.get("effects") or {}).get("diffraction", {}).get("included")
    if not included or "wavelengths_nm" not in info:
        return None
    waves = info["wavelengths_nm"]
    return {
        "wavelength_nm": float(waves[1] if len(waves) == 3 else waves[0]),
        "pixel_pitch_mm": info.get("pixel_pitch_mm"),
    }


def _diffracted(k, record: CaptureRecord, cam, size, build):
    """``k`` with the capture's diffraction (:func:`capture_diffraction`), when it has one:
    ``build(cam, f, shape)`` makes ``k``'s kernel on pixels f times finer, so that the pixel's
    box is counted once (:func:`~pacam_render.psf.diffraction.diffracted_kernel`); without
    ``size``, the far rings' last 1 % are left out (``DECONVOLUTION_MAX_LOST``)."""
    d = capture_diffraction(record)
    if d is None or record.mode == "reference":
        return k
    from ..psf.diffraction import DECONVOLUTION_MAX_LOST, diffracted_kernel

    wl, pitch = d["wavelength_nm"], d["pixel_pitch_mm"]
    lost = DECONVOLUTION_MAX_LOST if size is None else None
    return diffracted_kernel(build, cam, record.mode, wl, k.shape, pitch, lost)


def analytic_psf(record: CaptureRecord, s: float = 0.0, size=None):
    """The analytic PSF of a recorded capture at speed s (px/ms), registered to the pinhole
    image as the ``reference`` capture and the scene are (``origin="pinhole"``); with the
    capture's diffraction, when it includes it (:func:`capture_diffraction`)."""
    from ..model.camera import CameraDesign
    from ..psf.analytic import design_psf

    cam = CameraDesign.from_inputs(record.camera)
    k = design_psf(cam, record.mode, s, size, origin="pinhole")

    def build(c, f, fine):
        return design_psf(c, record.mode, s * f, fine, origin="pinhole")

    return _diffracted(k, record, cam, size, build)


def robust_psf(record: CaptureRecord, size=None):
    """The speed-robust analytic PSF of a recorded capture: averaged over the design's invariant
    range (:func:`~pacam_render.psf.robust.speed_robust_psf`), registered as :func:`analytic_psf`,
    with the capture's diffraction as there.
    """
    from ..model.camera import CameraDesign
    from ..psf.robust import speed_robust_psf

    cam = CameraDesign.from_inputs(record.camera)
    k = speed_robust_psf(cam, record.mode, size=size, origin="pinhole")

    def build(c, f, fine):
        return speed_robust_psf(c, record.mode, size=fine, origin="pinhole")

    return _diffracted(k, record, cam, size, build)
