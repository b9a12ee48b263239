"""Exposures: scenes and point sources rendered through the camera over a whole exposure 2T.

:mod:`.capture` renders a capture (:class:`CaptureSpec` in, from :mod:`.capture_spec`;
:class:`Capture` out) through the camera of :mod:`.capture_camera` as the mean of independent
passes (:mod:`.integrate`): one render per pass for a static scene, or, for a moving one, time
steps within each aperture pattern's window (:mod:`.steps`), each at a random time, resumable
from disk (:mod:`.checkpoint`). The passes' spread is the capture's Monte Carlo error
(:mod:`.estimate`), and :mod:`.progress` renders passes until a sample budget or a noise target
is met. :mod:`.record` is its typed JSON sidecar (:class:`CaptureRecord`), which
:mod:`.capture_record` builds. :mod:`.psf_render`
ray-traces PSFs of a camera design (:func:`render_psf`, :class:`PSFRenderer`), registered with
the analytic kernels of :mod:`pacam_render.psf`. Importing this package imports neither
Mitsuba nor Dr.Jit; they load on the first render. Units: mm, ms, px; velocities px/ms,
accelerations px/ms^2.
"""

from .capture import Capture, CaptureInterrupted, render_capture, write_capture
from .capture_spec import CaptureSpec, check_crop, parse_crop
from .psf_render import PSFRenderer, render_psf
from .psf_spec import PSFSpec
from .record import CaptureRecord, SensorRecord

__all__ = [
    "Capture",
    "CaptureInterrupted",
    "CaptureRecord",
    "CaptureSpec",
    "PSFRenderer",
    "PSFSpec",
    "SensorRecord",
    "check_crop",
    "parse_crop",
    "render_capture",
    "render_psf",
    "write_capture",
]
