"""The image sensor on a capture already on disk: one render, any number of light levels.

``pacam render --sensor`` adds the sensor while it renders; :func:`sensor_on_capture` does the
same to a capture read back from ``capture.exr`` and its JSON (rendered with or without a
sensor: its noise-free ``capture`` layer is what the sensor sees, so an earlier sensor's
``raw`` and ``noisy`` are replaced). With the capture's own seed it draws the noise that
``render --sensor`` would have drawn.
"""

from __future__ import annotations

import os
import re
import warnings

from ..capture.files import read_capture_layers
from ..capture.result import Capture
from ..errors import ParameterError
from ..limits import PacamWarning
from .apply import add_sensor_layers
from .model import SensorModel

SENSOR_LAYERS = ("raw", "noisy")
"""The layers the sensor adds (and replaces)."""
_PATTERN = re.compile(r"sub(\d+)$")


def load_capture(path: str | os.PathLike) -> Capture:
    """A capture read back as :func:`~pacam_render.exposure.direct.render_capture` returned
    it: the image and every layer in the file's own units, the per-pattern images and the
    per-pixel Monte Carlo sigma when the file has them, and its record."""
    layers, record = read_capture_layers(path)
    if "capture" not in layers:
        raise ParameterError(f"{path} has no 'capture' layer: it is not a pacam capture")
    patterns = {int(m.group(1)): v for k, v in layers.items() if (m := _PATTERN.match(k))}
    keep = {k: v for k, v in layers.items() if not _PATTERN.match(k)}
    image, mc_sigma = keep.pop("capture"), keep.pop("mc_sigma", None)
    return Capture(image, patterns, record, keep, mc_sigma)


def sensor_on_capture(
    path: str | os.PathLike, preset: str, light_level: float | None = None, seed: int | None = None
) -> Capture:
    """Read a capture and pass it through the image sensor, as ``render --sensor`` does.

    Parameters
    ----------
    path : path-like
        ``capture.exr`` (or its folder), with its JSON beside it.
    preset : str
        A sensor preset (``SensorModel.from_preset``).
    light_level : float, optional
        Photons/px/ms from white at the full aperture; None: the preset's default
        (:func:`~pacam_render.sensor.apply.add_sensor_layers`).
    seed : int, optional
        The noise's seed; None: the capture's own, which gives what ``render --sensor``
        with that seed gives.

    Returns
    -------
    Capture
        With ``raw`` and ``noisy`` added (or replaced) and the sensor in its record.
    """
    model = SensorModel.from_preset(preset)
    cap = load_capture(path)
    rec = cap.record
    if rec.sensor is not None or any(k in cap.extra_layers for k in SENSOR_LAYERS):
        note = (
            f"the capture's sensor ({rec.sensor.preset if rec.sensor else 'unknown'}) is "
            f"replaced by {preset}: its raw and noisy layers are drawn again"
        )
        warnings.warn(note, PacamWarning, stacklevel=2)
        rec.notes.append(note)
        for k in SENSOR_LAYERS:
            cap.extra_layers.pop(k, None)
        rec.sensor, rec.noise_sigma = None, None
    seed = int(rec.spec.get("seed", 0)) if seed is None else seed
    add_sensor_layers(cap, model, preset, light_level, seed)
    return cap
