"""Bitmap designs on the cells of a :class:`~pacam_render.lightfield.cell_basis.CellBasis`:
a design's discs rasterised on the cells (as the LCoS shows them), and a code written as a
design file whose masks ``pacam render --design`` reads."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import ParameterError
from ..exposure.plan import plan_capture
from ..model.design_file import as_read_back, write_design
from ..model.masks import DISPLAY_SHAPE, MaskStack, disc_masks


def cell_centres_mm(cells: int, R_max_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Design-frame centres (x to the image's right, y downwards, mm) of a G x G grid's
    columns and rows over the clear aperture's square [-R_max, R_max]^2."""
    pitch = 2.0 * R_max_mm / cells
    c = (np.arange(cells) + 0.5 - cells / 2.0) * pitch
    return c, c


def disc_code(plan, cells: int) -> np.ndarray:
    """(n, G, G) binary code of ``plan``'s design: cell open where its centre lies in pattern
    k's disc (radius R about ``pattern_centres_xy_mm()[k]``, design frame), closed patterns 0."""
    cam = plan.cam
    if cam.pattern_masks is not None:
        raise ParameterError("disc_code rasterises a disc schedule; this design is a bitmap")
    x, y = cell_centres_mm(cells, cam.R_max_mm)
    centres = np.asarray(cam.pattern_centres_xy_mm(), float)
    d2 = (x[None, None, :] - centres[:, 0, None, None]) ** 2 + (
        y[None, :, None] - centres[:, 1, None, None]
    ) ** 2
    is_open = np.asarray(plan.aperture(plan.sensor_params()).is_open)
    return ((d2 <= cam.R_mm**2) & is_open[:, None, None]).astype(float)


def bitmap_design(plan, basis, code, name: str = "pacam optimize --space bitmap"):
    """The base design of ``plan`` at its full sensor size showing ``code`` on ``basis``'s
    cells (:meth:`~pacam_render.lightfield.cell_basis.CellBasis.masks`), its opening R the
    masks' equivalent radius (the camera its design file reads back as)."""
    stack = MaskStack(basis.masks(code), basis.pitch_mm, name="cell code")
    d = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px)
    return as_read_back(d.with_(pattern_centres_mm=None, pattern_masks=stack,
                                quoted_a_i_px_per_ms2=None, name=name))  # fmt: skip


def fine_disc_design_spec(spec, path):
    """``spec`` with its design's discs as a bitmap design file at ``path``: each pattern the
    LCoS pixels (its native :data:`~pacam_render.model.masks.DISPLAY_SHAPE`) whose centre lies
    in the disc (:func:`~pacam_render.model.masks.disc_masks`, whose centres are in the
    camera's frame: minus the design's), closed patterns dark; the
    reference a cell grid's rasterisation is measured against (``bench_cell_grid.py``)."""
    plan = plan_capture(spec)
    cam = plan.cam
    if cam.pattern_masks is not None:
        raise ParameterError("fine_disc_design_spec rasterises a disc schedule; this is a bitmap")
    if getattr(spec, "lcos_contrast", None) is not None:
        raise ParameterError("fine_disc_design_spec: an ideal LCoS (lcos_contrast None) only")
    local = -np.asarray(cam.pattern_centres_xy_mm(), float)  # disc_masks: the camera's frame
    masks = disc_masks(local, cam.R_mm, DISPLAY_SHAPE, cam.lcos_pitch_mm)
    masks *= np.asarray(plan.aperture(plan.sensor_params()).is_open, np.float32)[:, None, None]
    stack = MaskStack(masks, cam.lcos_pitch_mm, name="fine disc")
    d = plan.design.with_(width_px=plan.full.width_px, height_px=plan.full.height_px)
    write_design(path, as_read_back(d.with_(pattern_centres_mm=None, pattern_masks=stack,
                                            quoted_a_i_px_per_ms2=None,
                                            name="the design's discs on the LCoS pixels")),
                 force=True)  # fmt: skip
    return dataclasses.replace(spec, design=str(path))


def bitmap_design_spec(spec, basis, code, path):
    """``spec`` with ``code``'s bitmap design, through a design file at ``path`` (the user's
    road: its masks written beside it and read back)."""
    write_design(path, bitmap_design(plan_capture(spec), basis, code), force=True)
    return dataclasses.replace(spec, design=str(path))


def design_spec(spec, path):
    """``spec`` with the design file at ``path`` in place of its own schedule."""
    return dataclasses.replace(spec, design=str(path), cover_px_per_ms=None, f_number=None,
                               r_px=None, schedule=None)  # fmt: skip
