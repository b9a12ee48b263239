"""Captures as data: what every producer of captures writes and every reader reads.

:mod:`.record` is the typed record and its JSON sidecar (:class:`CaptureRecord`, the layers'
units), :mod:`.result` a finished capture in memory (:class:`Capture`), :mod:`.files` reads a
capture's files back on one scale, :mod:`.kernels` gives the analytic kernels a record
describes, and :mod:`.optics_error` is the record's physics error budget. It sits below
:mod:`pacam_render.sensor`, :mod:`pacam_render.restore` and the producers
(:mod:`pacam_render.exposure`), so that none of them imports upwards to reach it.
"""

from .files import CaptureFile, read_capture, read_capture_layers, read_record
from .record import CaptureRecord, SensorRecord
from .result import Capture

__all__ = [
    "Capture",
    "CaptureFile",
    "CaptureRecord",
    "SensorRecord",
    "read_capture",
    "read_capture_layers",
    "read_record",
]
