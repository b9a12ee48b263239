"""A capture's files read back: ``capture.exr`` with its ``capture.json`` sidecar, checked to be
one capture, and its layers on one scale (:func:`read_capture`)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import ParameterError, check_positive
from ..io.arrays import read_json
from ..io.exr import read_exr
from ..limits import PacamWarning
from ..model.illumination import flat_field
from .record import CAPTURE_UNIT, WHITE_UNIT, CaptureRecord, image_size, layer_unit


class CaptureFile(NamedTuple):
    """A capture read by :func:`read_capture`: its layers on one scale, and its record."""

    layers: dict[str, np.ndarray]
    """Every layer of ``capture.exr``; those in :data:`CAPTURE_UNIT` divided by
    ``light_factor``, so they and ``sharp`` are all in :data:`WHITE_UNIT`."""
    record: CaptureRecord
    units: dict[str, str]
    """Each returned layer to its unit (None for a layer this version does not know)."""


def check_layers_fit(layers: dict, record: CaptureRecord | None, exr, sidecar) -> None:
    """Refuse an EXR and a JSON that disagree on the image's size (a kernel in px made from
    the JSON would be the wrong one)."""
    size = None if record is None else image_size(record)
    if size is None:
        return
    for name, a in layers.items():
        h, w = np.shape(a)[:2]
        if (w, h) != size:
            raise ParameterError(
                f"{exr} and {sidecar} disagree: layer {name!r} is {w}x{h} px, the JSON says "
                f"{size[0]}x{size[1]}; they are not one capture"
            )


def read_capture_layers(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], CaptureRecord]:
    """A capture's layers as stored (:data:`LAYER_UNITS`) and its record.

    Parameters
    ----------
    path : path-like
        ``capture.exr``, or the folder that holds it; its JSON must be beside it.

    Raises
    ------
    ParameterError
        If a file is missing or unreadable.
    """

    exr = Path(path)
    exr = exr / "capture.exr" if exr.is_dir() else exr
    sidecar = exr.with_suffix(".json")
    if not exr.is_file():
        raise ParameterError(f"no capture at {exr}")
    if not sidecar.is_file():
        raise ParameterError(f"{exr} has no {sidecar.name} beside it: its scale is not known")
    record = CaptureRecord.from_json(read_json(sidecar, "capture record"), where=str(sidecar))
    layers = read_exr(exr)
    check_layers_fit(layers, record, exr, sidecar)
    return layers, record


def read_record(capture: str | os.PathLike, required: bool = True) -> CaptureRecord | None:
    """The record of ``capture.exr`` from its JSON sidecar, or None if it has none.

    Parameters
    ----------
    capture : path-like
        The capture's EXR file; its record is the ``.json`` of the same name beside it.
    required : bool
        Whether the record must be complete (a camera, ...). If False, a sidecar that is valid
        JSON but not a complete record gives a :class:`~pacam_render.limits.PacamWarning` and
        None: only its noise sigma would have been used.

    Returns
    -------
    CaptureRecord or None

    Raises
    ------
    ParameterError
        If the sidecar is not valid JSON, or (``required``) not a complete record.
    """
    import warnings

    path = Path(capture).with_suffix(".json")
    if not path.is_file():
        return None
    data = read_json(path, "capture record")
    try:
        return CaptureRecord.from_json(data, where=str(path))
    except ParameterError as exc:
        if required:
            raise
        warnings.warn(f"{exc}; its noise sigma is not used", PacamWarning, stacklevel=2)
        return None


def read_capture(path: str | os.PathLike) -> CaptureFile:
    """Read a capture (``capture.exr`` and its JSON) with every image layer on the white scale.

    A capture's own layers (``capture``, ``noisy``, ``subNN``, ``mc_sigma``) are radiance x
    ``light_factor``, its ground truth ``sharp`` plain radiance; this divides the former by
    ``light_factor``, so that e.g. a PSNR of ``noisy`` against ``sharp`` means what it says.
    A capture with a relative illumination (its ``relative_illumination`` layer, the map m)
    measured irradiance; its own layers are also divided by m (flat-fielded, as a camera
    pipeline does: the noise grows by 1 / m towards the corners), so they are radiance again.

    Parameters
    ----------
    path : path-like
        The ``capture.exr`` file, or the folder that holds it; ``capture.json`` (the same
        name, ``.json``) must be beside it.

    Returns
    -------
    CaptureFile
        ``layers`` (float32, white = 1; ``raw`` stays in DN, ``depth`` in mm, ...), ``record``
        (the :class:`CaptureRecord`, unchanged: ``light_factor`` still says the file's scale)
        and ``units`` (each returned layer's unit).

    Raises
    ------
    ParameterError
        If a file is missing or unreadable, or ``light_factor`` is not > 0.
    """

    stored, record = read_capture_layers(path)
    lf = check_positive("light_factor in the capture's JSON", record.light_factor)

    ri_map = stored.get("relative_illumination")
    layers, units = {}, {}
    for name, arr in stored.items():
        unit = layer_unit(name)
        scaled = unit is not None and unit.startswith(CAPTURE_UNIT)
        layers[name] = flat_field(arr / np.float32(lf), ri_map) if scaled else arr
        units[name] = unit.replace(CAPTURE_UNIT, WHITE_UNIT) if scaled else unit
    return CaptureFile(layers, record, units)
