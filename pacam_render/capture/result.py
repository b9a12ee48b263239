"""A finished capture in memory: its image, its layers and its record, as every producer of
captures returns it (:func:`pacam_render.exposure.direct.render_capture`) and every stage after
the render takes it (the sensor, the writer)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .record import CaptureRecord


@dataclass
class Capture:
    """A finished capture: the image, optional per-pattern images, extra layers (the sensor's
    ``raw`` and ``noisy``), and its :class:`~pacam_render.capture.record.CaptureRecord`."""

    image: np.ndarray
    patterns: dict[int, np.ndarray]
    record: CaptureRecord
    extra_layers: dict[str, np.ndarray] = field(default_factory=dict)
    mc_sigma: np.ndarray | None = None
    """Per-pixel Monte Carlo sigma of ``image``, its units (``record.render_error`` sums it up)."""

    @property
    def meta(self) -> dict:
        """The record as a dict, ``optics`` and ``coded_design`` both filled (a fresh dict:
        change ``record``); the sidecar (:meth:`.CaptureRecord.to_json`) writes a repeated
        design once."""
        return self.record.to_json(compact=False)
