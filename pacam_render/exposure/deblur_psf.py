"""The PSF a capture is deblurred with: analytic or speed-robust from its record, or a kernel
file (an EXR that ``pacam psf`` wrote, with its ``psf.json``, or a bare ``.npy``), checked
against the capture's sensor size, with the image point its centre pixel stands for."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from ..capture.kernels import CapturePSF, capture_diffraction, named_psf
from ..capture.record import CaptureRecord
from ..errors import ParameterError
from ..io.arrays import read_json, read_npy
from ..io.exr import read_exr
from ..limits import PacamWarning
from ..model.camera import CameraDesign
from ..psf.origin import recorded_origin

PSF_SOURCES = ("analytic", "robust", "rendered")
"""The kernels named rather than given by path: from the record, or ``psf_rendered.exr``."""


class PSFMismatchError(ParameterError):
    """A kernel file made for another camera than the capture's."""


_FIGURES = (  # (psf.json key, words, format): what a user compares, in this order
    ("mode", "mode", "{}"),
    ("r_px", "r", "{:.4g} px"),
    ("a_i_px_per_ms2", "a_i", "{:.4g} px/ms^2"),
    ("n_patterns", "pattern count", "{}"),
    ("exposure_ms", "exposure", "{:g} ms"),
    ("object_depth_mm", "depth", "{:g} mm"),
    ("schedule_kind", "schedule", "{}"),
)


def psf_mismatch(meta: dict, record: CaptureRecord) -> tuple[str, ...]:
    """How the camera a kernel file was made for differs from the capture's: one phrase per
    differing figure (``"r 2 px (PSF) against 3.126 px (capture)"``), then the design digest
    if only it differs; empty when they are the same camera. Velocity and crop are not
    compared: a kernel for another speed, or a window, is still this camera's."""

    cam = CameraDesign.from_inputs(record.camera)
    mine = {**cam.summary(), "mode": record.mode}
    out = []
    for key, words, fmt in _FIGURES:
        a, b = meta.get(key), mine.get(key)
        if (
            a is None
            or a == b
            or (isinstance(a, float) and isinstance(b, float) and abs(a - b) <= 1e-9 * abs(b))
        ):
            continue
        out.append(f"{words} {fmt.format(a)} (PSF) against {fmt.format(b)} (capture)")
    if "diffraction" in meta:  # psf.json from before diffraction compares nothing here
        words = {True: "diffraction included", False: "no diffraction"}
        pd, cd = meta["diffraction"], capture_diffraction(record)
        a, b = pd is not None, cd is not None
        if a != b:
            out.append(f"{words[a]} (PSF) against {words[b]} (capture)")
        elif a and isinstance(pd, dict) and pd.get("psf", "fraunhofer") != cd["psf"]:
            out.append(f"{pd.get('psf', 'fraunhofer')} defocused PSF (PSF) against "
                       f"{cd['psf']} (capture)")  # fmt: skip
    digest = meta.get("design_digest")
    if not out and digest is not None and digest != mine["design_digest"]:
        out.append(f"design digest {digest} (PSF) against {mine['design_digest']} (capture)")
    return tuple(out)


def check_psf_design(path: Path, meta: dict | None, record: CaptureRecord | None, allow: bool):
    """The kernel file's camera against the capture's (:func:`psf_mismatch`).

    Raises
    ------
    PSFMismatchError
        On a mismatch, naming both values of each figure, unless ``allow`` (a deliberate
        mismatch, as in Fig. 9's wrong assumed depth): then a note says it.
    """
    if not isinstance(meta, dict):
        return ()
    sidecar = path.parent / "psf.json"
    if record is None:  # a capture.exr without its capture.json
        made = ", ".join(f"{w} {f.format(meta[k])}" for k, w, f in _FIGURES if k in meta)
        warnings.warn(
            f"the capture has no capture.json: the camera {sidecar} was made for "
            f"({made or 'not recorded'}) cannot be checked against the capture's",
            PacamWarning,
            stacklevel=2,
        )
        return ()
    if "design_digest" not in meta:
        known = [w for k, w, _ in _FIGURES if k in meta]
        what = f"only its {', '.join(known)} are" if known else "nothing is"
        warnings.warn(
            f"{sidecar} records no design digest (an older pacam, or an edit): {what} checked "
            "against the capture's; remake it with pacam psf `like` CAPTURE.exr",
            PacamWarning,
            stacklevel=2,
        )
    diff = psf_mismatch(meta, record)
    if diff and not allow:
        raise PSFMismatchError(
            f"`psf` {path} was made for another camera than the capture's: "
            + "; ".join(diff)
            + ". Make the kernel with pacam psf `like` CAPTURE.exr, or pass "
            "allow_psf_mismatch to deblur with it on purpose (e.g. a wrong assumed depth)"
        )
    if diff:
        warnings.warn("deblurring with a mismatched PSF: " + "; ".join(diff), PacamWarning, 2)
    return diff


def psf_path(psf: str, capture: str | os.PathLike) -> Path | None:
    """The file that ``psf`` reads: None for ``analytic`` and ``robust`` (from the record),
    ``psf_rendered.exr`` beside the capture for ``rendered``, else ``psf`` itself."""
    if psf in ("analytic", "robust"):
        return None
    return Path(capture).parent / "psf_rendered.exr" if psf == "rendered" else Path(psf)


def load_capture_psf(
    psf: str,
    capture: str | os.PathLike,
    record: CaptureRecord | None,
    allow_psf_mismatch: bool = False,
) -> CapturePSF:
    """The kernel to deblur ``capture`` with.

    Parameters
    ----------
    psf : str
        ``analytic`` (the s = 0 PSF of the capture's mode and design), ``robust`` (averaged
        over the design's speed range), ``rendered`` (``psf_rendered.exr`` beside the capture)
        or the path of an ``.exr`` (a ``psf`` layer, or its only layer) or ``.npy`` kernel.
    capture : path-like
        The capture's EXR file.
    record : CaptureRecord or None
        The capture's record; ``analytic`` and ``robust`` need it, and a kernel file is
        checked against its sensor size and camera (:func:`check_psf_design`).
    allow_psf_mismatch : bool
        Deblur with a kernel file made for another camera (noted, and recorded in
        :attr:`CapturePSF.mismatch`) instead of refusing it.

    Returns
    -------
    CapturePSF
        The kernel, its file (None when computed), its origin (``pinhole`` or ``t0``) and the
        t = 0 image's offset from the pinhole image, px.

    Raises
    ------
    ParameterError
        If the record is missing, the file is missing or unreadable, or the kernel was made for
        another sensor size.
    """
    capture = Path(capture)
    if psf in ("analytic", "robust"):
        if record is None:
            path = capture.with_suffix(".json")
            raise ParameterError(f"`psf` {psf} needs the capture's parameters in {path}")
        return named_psf(psf, record)
    path = psf_path(psf, capture)
    if psf == "rendered" and not path.is_file():
        raise ParameterError(
            f"`psf` rendered reads {path}, which does not exist; make it with pacam psf "
            f"`like` {capture} `velocity` 0 `render` `out` {capture.parent} (the capture's "
            "own camera, depth and mode), or use `psf` analytic"
        )
    meta = psf_sidecar(path)
    check_psf_scale(path, meta, capture, record)
    diff = check_psf_design(path, meta, record, allow_psf_mismatch)
    origin, offset = psf_origin(path, meta)
    if path.suffix == ".npy":
        return CapturePSF(_summed(load_npy_psf(path), path), path, origin, offset, diff)
    layers = read_exr(path)
    if "psf" in layers:
        return CapturePSF(_summed(layers["psf"], path), path, origin, offset, diff)
    if len(layers) == 1:
        k = next(iter(layers.values()))
        return CapturePSF(_summed(k, path), path, origin, offset, diff)
    raise ParameterError(f"{path} has no 'psf' layer; it has: {', '.join(sorted(layers))}")


SUM_TOLERANCE = 1e-3
"""A kernel file whose sum is further than this from 1 is normalised with a note."""


def _summed(k: np.ndarray, path: Path) -> np.ndarray:
    """A kernel file's values, refused if they sum to nothing (not finite, or below 1e-12 of
    their largest magnitude), with a note if they sum to other than 1 (they are normalised
    before deblurring, as every PSF is)."""
    total = float(np.sum(k, dtype=np.float64))
    scale = float(np.max(np.abs(k))) if np.size(k) else 0.0
    if not np.isfinite(total) or total <= 1e-12 * max(scale, 1e-300):
        raise ParameterError(f"`psf` file {path} sums to {total:g}: it holds no PSF")
    if abs(total - 1.0) > SUM_TOLERANCE:
        warnings.warn(
            f"`psf` file {path} sums to {total:.6g}, not 1: it is normalised to 1 (a PSF "
            "spreads the light it receives)",
            PacamWarning,
            stacklevel=3,
        )
    return k


def psf_sidecar(path: Path) -> dict | None:
    """The ``psf.json`` that ``pacam psf`` wrote beside an EXR kernel, or None."""
    sidecar = path.parent / "psf.json"
    if path.suffix == ".npy" or not sidecar.is_file():
        return None

    meta = read_json(sidecar, "kernel record")
    return meta if isinstance(meta, dict) else None


def psf_origin(path: Path, meta: dict | None) -> tuple[str, float]:
    """The kernel's origin and t = 0 offset (px) from its psf.json. A kernel without one is
    taken as centred like the capture (the pinhole image); an older t0 file, which lacks the
    offset, is used as it is, with a note."""

    origin, offset = recorded_origin(meta or {})
    if origin == "t0" and offset is None:
        warnings.warn(
            f"{path} is centred on the t = 0 image but its psf.json (from an older pacam) does "
            "not record how far that lies from the pinhole image, so the result is not moved "
            "onto the capture's registration; remake it with pacam psf `like` CAPTURE.exr",
            PacamWarning,
            stacklevel=2,
        )
        return "pinhole", 0.0
    return origin or "pinhole", offset or 0.0


def check_psf_scale(
    path: Path, meta: dict | None, capture: Path, record: CaptureRecord | None
) -> None:
    """Refuse a kernel made for another sensor size than the capture's (px scale differs); a
    kernel that records no size gets a note."""
    sidecar = path.parent / "psf.json"
    if not isinstance(meta, dict) or "width_px" not in meta:
        warnings.warn(
            f"{path} records no sensor size: make sure it was made at the capture's scale "
            f"(pacam psf `like` {capture})",
            PacamWarning,
            stacklevel=2,
        )
        return
    if record is None or "width_px" not in record.camera:
        return
    made = (meta["width_px"], meta.get("height_px"))
    needed = (record.camera["width_px"], record.camera.get("height_px"))
    if made != needed:
        raise ParameterError(
            f"`psf` {path} was made for a {made[0]}x{made[1]} sensor ({sidecar}), the capture "
            f"for {needed[0]}x{needed[1]}: its px are a different size; make the kernel with "
            f"pacam psf `like` {capture} ..."
        )


def load_npy_psf(path: Path) -> np.ndarray:
    """A kernel from a ``.npy`` file: numbers only (never unpickle a file from elsewhere)."""

    return read_npy(path, "`psf` file")
