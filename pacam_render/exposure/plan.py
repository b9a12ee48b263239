"""A capture resolved once: :class:`CapturePlan`, which every stage of a capture reads.

A :class:`~pacam_render.exposure.spec.CaptureSpec` says what to capture in the user's words (a
preset or a design file, a speed to cover, a schedule, the optics settings). :func:`plan_capture`
turns it into what is rendered: the Mitsuba variant, the design read once
(:func:`~pacam_render.exposure.camera.full_design`, the one call of the resolver per capture), the
design at the capture's resolution, the mode's camera, the sensor's parameters, the film's pixel
pitch, and the notes the user is told about the camera. The render, the ground truth, diffraction's
decision, the optics budget and the record all read the plan instead of resolving the spec
again, and a second producer of captures builds the same plan and writes the same record.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

from ..errors import ParameterError
from ..limits import PacamWarning, note
from ..model import paper
from ..model.camera import CameraDesign
from ..model.modes import mode as mode_of
from ..model.optics import focal_length_px
from ..render.backend import select_variant
from ..render.plan import PROP_KEYS, build_plan
from ..render.variant import grey_request, is_mono
from ..sensor.model import SensorModel
from .camera import (
    binned_pitch_mm,
    contrast_params,
    full_design,
    illumination_params,
    mode_camera,
    note_binning,
    note_ignored_options,
    scaled_design,
    switching_params,
)
from .optics.budget import diffraction_params
from .spec import CaptureSpec


@dataclass(frozen=True)
class CapturePlan:
    """One capture, resolved: what every stage reads (module docstring).

    Attributes
    ----------
    spec : CaptureSpec
        The request; ``grey`` is set where the variant is a mono one.
    variant : str
        The Mitsuba variant it renders in.
    full : CameraDesign
        The design at its own full sensor size, as read (a design file's, or the preset's).
    design : CameraDesign
        The coded design at the capture's resolution (solved to cover a speed, or from a
        schedule file, as the spec asks).
    cam : CameraDesign
        The mode's camera (:func:`~pacam_render.exposure.camera.mode_camera`): its focus, opening
        and exposure, whose analytic PSF is ``design_psf(cam, mode)``.
    mode_params : dict
        The ``programmable_aperture`` parameters that show the mode (lengths in mm).
    optics_params : dict
        The sensor's relative-illumination, LCoS contrast and switching parameters.
    pitch_mm : float
        The pitch of the capture's pixels on the real sensor, mm (binned from ``full``).
    design_digest : str or None
        The digest of the design file's design as read (None for a preset): the resume key's.
    notes : tuple of str
        What the user is told about the camera while it is resolved.
    diffraction : tuple of (bool, str), optional
        Whether the openings' diffraction is in the capture, and the decision in words; None
        until :func:`~pacam_render.exposure.direct.render_capture` decides it (``auto`` renders a
        preview).
    """

    spec: CaptureSpec
    variant: str
    full: CameraDesign
    design: CameraDesign
    cam: CameraDesign
    mode_params: dict
    optics_params: dict
    pitch_mm: float
    design_digest: str | None = None
    notes: tuple[str, ...] = ()
    diffraction: tuple[bool, str] | None = field(default=None)

    @property
    def lens(self) -> bool:
        """Whether the mode sees through the lens (every mode but the pinhole reference)."""
        return mode_of(self.spec.mode).schedule is not None

    @property
    def window(self) -> tuple[int, int]:
        """(width, height) of the rendered image, px: the crop's, or the whole sensor's."""
        return self.spec.image_size

    def sensor_params(self) -> dict:
        """The ``programmable_aperture`` parameters of this capture: the mode's, then the
        relative illumination, the diffraction decided (none before it is), the LCoS's
        contrast and switching, in the order the record has always listed them."""

        on = self.diffraction is not None and self.diffraction[0]
        ri = {k: v for k, v in self.optics_params.items() if k in ("relative_illumination",
                                                                  "pixel_pitch")}  # fmt: skip
        lcos = {k: v for k, v in self.optics_params.items() if k not in ri}
        diff = diffraction_params(self.spec, self.cam, on, self.pitch_mm)
        return {**self.mode_params, **ri, **diff, **lcos}

    def aperture(self, params: dict | None = None):
        """The :class:`~pacam_render.render.plan.AperturePlan` the plugin builds from
        ``params`` (default :meth:`sensor_params`), without Mitsuba; a lens mode only."""

        if not self.lens:
            raise ParameterError("mode reference is a pinhole: render it directly (it has no lens)")
        params = self.sensor_params() if params is None else params
        cfg = {k: params[k] for k in PROP_KEYS if k in params}
        cfg["reference_exposure"] = paper.EXPOSURE_MS
        f_px = focal_length_px(self.cam.fov_deg, self.spec.width)
        return build_plan(cfg, 0.0, self.cam.exposure_ms, focal_px=f_px,
                          focus_mm=params["focus_distance"])  # fmt: skip

    def with_diffraction(self, on: bool, decision: str) -> CapturePlan:
        """This plan with diffraction decided: in the capture or not, and why."""
        return replace(self, diffraction=(bool(on), decision))

    def with_spec(self, **changes) -> CapturePlan:
        """This plan for a spec that differs only in how it samples (``spp``, ``passes``,
        ``sampler``, ``per_pattern``, ``diffraction``): the camera is the same, not resolved
        again (``auto``'s preview)."""
        sampling = {"spp", "passes", "sampler", "per_pattern", "diffraction"}
        if not set(changes) <= sampling:
            raise ValueError(f"with_spec changes sampling only ({sorted(sampling)})")
        return replace(self, spec=replace(self.spec, **changes), diffraction=None)

    def key(self) -> str:
        """The spec's resume key (:meth:`~pacam_render.exposure.spec.CaptureSpec.key`), with the
        design's digest from this plan rather than from the file read again."""
        return self.spec.key(design_digest=self.design_digest)

    def replay_notes(self) -> None:
        """Say the plan's notes again, where a capture records what it was told."""
        for text in self.notes:
            note(text)


def plan_capture(spec: CaptureSpec) -> CapturePlan:
    """Resolve a capture once (module docstring).

    Parameters
    ----------
    spec : CaptureSpec
        What to capture.

    Returns
    -------
    CapturePlan
        The variant, the design as read and at the capture's size, the mode's camera, the
        sensor's parameters and pixel pitch, and the notes said while resolving them;
        diffraction is not decided yet.

    Raises
    ------
    ParameterError
        If the design cannot be read or built, or the solver cannot cover the speed.

    Notes
    -----
    Selects and activates the Mitsuba variant (the mono one for ``spec.grey``; under a mono
    ``PACAM_VARIANT`` the plan's spec says ``grey`` too). Reads the design file or preset
    once: every later figure (the capture's pixel pitch, the binning note, the resume key)
    comes from this read.
    """

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PacamWarning)
        full, digest = _read_design(spec)
        spec = grey_for_sensor(spec, full.sensor_preset, "the design's sensor")
    variant = select_variant(mono=spec.grey)
    if is_mono(variant) and not spec.grey:  # PACAM_VARIANT=llvm_ad_mono: a grey capture
        spec = replace(spec, grey=True)
    with warnings.catch_warnings(record=True) as more:
        warnings.simplefilter("always", PacamWarning)
        note_ignored_options(spec)
        design = scaled_design(spec, full)
        cam, mode_params = mode_camera(design, spec.mode)
        pitch = binned_pitch_mm(full, spec.width)  # a depth changes neither pitch nor size
        optics = {
            **illumination_params(spec, pitch),
            **contrast_params(spec, mode_params),
            **switching_params(spec, mode_params, cam),
        }
        note_binning(spec, cam, full)
    caught = caught + more
    others = [w for w in caught if not issubclass(w.category, PacamWarning)]
    for w in others:  # not ours: shown as they were
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    notes = tuple(str(w.message) for w in caught if issubclass(w.category, PacamWarning))
    return CapturePlan(spec, variant, full, design, cam, mode_params, optics, pitch, digest, notes)


def grey_for_sensor(spec: CaptureSpec, preset: str | None, whose: str) -> CaptureSpec:
    """``spec`` grey, with a note, when ``preset`` is a monochrome sensor (a physical sensor
    with no colour filter) and the capture is RGB: the sensor sees one channel, so the
    capture renders one (an RGB capture through it took the mono noise model per channel).
    ``whose`` names the sensor in the note."""
    if preset is None or spec.grey:
        return spec

    model = SensorModel.from_preset(preset)
    if model.bayer is not None or not model.shot_noise:
        return spec
    grey_request(True)  # refused under an RGB PACAM_VARIANT, naming it
    note(f"{whose} {preset} is monochrome: the capture renders one channel (grey), as `grey` "
         "would ask")  # fmt: skip
    return replace(spec, grey=True)


def _read_design(spec: CaptureSpec) -> tuple[CameraDesign, str | None]:
    """The design at its full size with the spec's depth, read once, and (for a design file)
    the digest of the file's design as read, which the resume key hashes."""
    depth = {} if spec.object_depth_mm is None else {"object_depth_mm": spec.object_depth_mm}
    if spec.design is None:
        return full_design(spec, **depth), None  # a preset's factory takes the depth
    read = full_design(spec)
    return (read.with_(**depth) if depth else read), read.digest()
