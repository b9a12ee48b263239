"""Captures: scenes rendered through the camera over a whole exposure 2T.

:mod:`.plan` resolves a capture once (:class:`CapturePlan`: the design, the mode's camera, the
sensor's parameters, the optics settings and their decisions, the window and the sampler), from
a :class:`CaptureSpec` (:mod:`pacam_render.exposure.spec`); every stage reads that plan.
:mod:`pacam_render.exposure.direct` renders it as the mean of independent passes
(:mod:`.integrate`): one render per pass for a static scene, or, for a moving one, time steps
within each aperture pattern's window (:mod:`.steps`), each at a random time, resumable from disk
(:mod:`.checkpoint`). The passes' spread is the capture's Monte Carlo error (:mod:`.estimate`), and
:mod:`.progress` renders passes until a sample budget or a noise target is met.
:mod:`pacam_render.exposure.assemble` builds the capture's record
(:class:`~pacam_render.capture.record.CaptureRecord`, which lives below its readers in
:mod:`pacam_render.capture`). Ray-traced PSFs are :mod:`pacam_render.psf_render`'s. Importing this
package imports neither Mitsuba nor Dr.Jit; they load on the first render. Units: mm, ms, px;
velocities px/ms, accelerations px/ms^2.
"""

from .direct import CaptureInterrupted, render_capture, write_capture
from .spec import CaptureSpec, check_crop, parse_crop

__all__ = [
    "CaptureInterrupted",
    "CaptureSpec",
    "check_crop",
    "parse_crop",
    "render_capture",
    "write_capture",
]
