"""The analytic camera model: a design, every quantity it implies, and the capture modes.

:class:`CameraDesign` (:mod:`.camera`) derives the paper's quantities (Sections 2.1-2.3: the
parallax factor beta, the defocus radius r = |beta| R of Eq. 12, the image acceleration
a_i = beta a_a of Eq. 18, the F-number) from what a camera engineer sets, in mm, ms and px;
:func:`prototype` follows Table 1 and Section 4. :func:`solve` (:mod:`.design`) finds the
opening and focus that make a speed range motion-invariant, :func:`design_report` explains a
design, and :mod:`.modes` is the one table of capture modes (:data:`MODES`) that captures,
rendered PSFs and analytic PSFs all read. :mod:`.optics`, :mod:`.schedule` and :mod:`.paper`
hold the thin-lens formulas, the aperture schedule and the paper's published values.
:mod:`.design_file` reads and writes a design as one TOML file (``--design FILE``),
:mod:`.masks` holds LCoS bitmap schedules (:class:`MaskStack`), and :mod:`.schedule_fit` fits
a_i and the invariant range to any schedule's own image trajectory.
"""

from .camera import PRESETS, CameraDesign, preset, prototype
from .design import solve
from .design_file import read_design, resolve_design, write_design
from .masks import MaskStack
from .modes import MODES, MODES_WITH_PSF, Mode, capture_camera, mode, sensor_params
from .report import design_report

__all__ = [
    "MODES",
    "MODES_WITH_PSF",
    "PRESETS",
    "CameraDesign",
    "MaskStack",
    "Mode",
    "capture_camera",
    "design_report",
    "mode",
    "preset",
    "prototype",
    "read_design",
    "resolve_design",
    "sensor_params",
    "solve",
    "write_design",
]
