"""The capture record: what a capture is, typed, and its JSON sidecar (``capture.json``).

One place builds it (:func:`pacam_render.exposure.capture.render_capture`), one place adds the
image sensor to it (:func:`pacam_render.sensor.apply.add_sensor_layers`), and one place reads it
back (:meth:`CaptureRecord.from_json`), so ``pacam render --sensor`` followed by ``pacam
deconvolve`` knows the capture's noise instead of estimating it.

The JSON keys are the ones earlier versions wrote; :meth:`CaptureRecord.from_json` also reads
the demo's older sensor block (``light_level`` for ``light_level_photons_per_px_per_ms``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

from ..errors import ParameterError
from ..model import paper

PIXEL_UNIT = "radiance x (open area / full aperture) x (exposure / 45 ms)"


@dataclass
class SensorRecord:
    """The image sensor a capture went through (:mod:`pacam_render.sensor`).

    ``noise_sigma_white_units``: the temporal noise sigma at the capture's mean level, with a
    white diffuse surface = 1 (what a deconvolver should assume, Fig. 8's noise level).
    """

    preset: str
    model: dict
    light_level_photons_per_px_per_ms: float | None
    photons_per_unit: float
    seed: int
    noise_sigma_white_units: float | None = None
    saturated_fraction: float | None = None
    """Fraction of values whose mean charge exceeds the sensor's saturation, before noise."""

    @classmethod
    def from_json(cls, d: dict) -> SensorRecord:
        level = d.get("light_level_photons_per_px_per_ms", d.get("light_level"))
        return cls(
            preset=d.get("preset", "unknown"),
            model=d.get("model", {}),
            light_level_photons_per_px_per_ms=level,
            photons_per_unit=d.get("photons_per_unit", float("nan")),
            seed=d.get("seed", 0),
            noise_sigma_white_units=d.get("noise_sigma_white_units"),
            saturated_fraction=d.get("saturated_fraction"),
        )


@dataclass
class CaptureRecord:
    """Everything about one capture but its pixels (the ``capture.json`` sidecar).

    Units: ``exposure_ms`` and ``reference_exposure_ms`` in ms; ``light_factor`` is the
    capture's brightness relative to the full aperture over 45 ms (so ``capture /
    light_factor`` reads a white diffuse surface as about its reflectance); ``noise_sigma`` is
    in the capture's own units (``noise_sigma_white_units x light_factor``).
    """

    spec: dict
    mode: str
    camera: dict
    optics: dict
    coded_design: dict
    sensor_params: dict
    exposure_ms: float
    reference_exposure_ms: float
    light_factor: float
    render_seconds: float
    variant: str
    versions: dict
    n_steps: int = 1
    n_geometry_updates: int = 0
    effective_spp: int = 0
    resumed_from_step: int | None = None
    fastest_image_speed_px_per_ms: float | None = None
    pixel_unit: str = PIXEL_UNIT
    sensor: SensorRecord | None = None
    noise_sigma: float | None = None
    notes: list[str] = field(default_factory=list)
    """What the user was told while the capture was made (``note:`` lines of the CLI)."""
    crop: dict | None = None
    """The window of the sensor rendered: x, y, width, height and the sensor's size, px."""
    objects: dict | None = None
    """The ``object_id`` layer's legend: id (a string) to shape id; 0 is no surface."""
    render_error: dict | None = None
    """The render's own error and its cost (:mod:`~pacam_render.exposure.estimate`):
    ``mc_sigma`` (RMS over the window, the capture's units), ``mc_sigma_white_units``,
    ``mc_sigma_by_object``, ``sharp_mc_sigma`` (white = 1), ``passes``, ``pass_spp``, ``spp``,
    ``sampler``, ``seconds``, the time steps' ``time_step_bias`` and ``time_sampling``, and,
    for a capture rendered to a target, ``target_sigma`` and ``target_met``; the sensor adds
    ``ratio_to_sensor``."""
    extra: dict = field(default_factory=dict)
    """Keys this version does not know (kept, and written back)."""

    def to_json(self) -> dict:
        """The JSON-ready dict; optional fields that are unset are left out."""
        out = {k: v for k, v in asdict(self).items() if k not in ("extra", "sensor")}
        optional = ("resumed_from_step", "fastest_image_speed_px_per_ms", "noise_sigma")
        for key in (*optional, "crop", "objects", "render_error"):
            if out[key] is None:
                del out[key]
        if self.sensor is not None:
            out["sensor"] = asdict(self.sensor)
        return {**self.extra, **out}

    @classmethod
    def from_json(cls, d: dict, where: str = "capture JSON") -> CaptureRecord:
        """Read a sidecar written by this or an earlier version."""
        if not isinstance(d, dict):
            raise ParameterError(f"{where}: expected a JSON object, got {type(d).__name__}")
        known = {f.name for f in fields(cls)} - {"extra", "sensor"}
        missing = [k for k in ("mode", "camera") if k not in d]
        if missing:
            raise ParameterError(
                f"{where} lacks {' and '.join(repr(k) for k in missing)}: it is not the JSON "
                f"of a pacam capture (pacam render writes one beside capture.exr)"
            )
        if not isinstance(d["camera"], dict):
            raise ParameterError(f"{where}: 'camera' must be an object of camera parameters")
        kw: dict[str, Any] = {k: d[k] for k in known if k in d}
        kw.setdefault("light_factor", 1.0)
        kw.setdefault("exposure_ms", d["camera"].get("exposure_ms", paper.EXPOSURE_MS))
        for k in ("spec", "optics", "coded_design", "sensor_params", "versions"):
            kw.setdefault(k, {})
        kw.setdefault("reference_exposure_ms", paper.EXPOSURE_MS)
        kw.setdefault("render_seconds", 0.0)
        kw.setdefault("variant", "unknown")
        sensor = SensorRecord.from_json(d["sensor"]) if isinstance(d.get("sensor"), dict) else None
        extra = {k: v for k, v in d.items() if k not in known and k != "sensor"}
        return cls(**kw, sensor=sensor, extra=extra)

    @property
    def known_noise_sigma(self) -> float | None:
        """The capture's noise sigma in its own units, if a sensor model gave it."""
        if self.noise_sigma is not None:
            return self.noise_sigma
        s = self.sensor
        if s is not None and s.noise_sigma_white_units is not None:
            return s.noise_sigma_white_units * self.light_factor
        return None


def analytic_psf(record: CaptureRecord, s: float = 0.0, size=None):
    """The analytic PSF of a recorded capture at speed s (px/ms), registered to the pinhole
    image as the ``reference`` capture and the scene are (``origin="pinhole"``)."""
    from ..model.camera import CameraDesign
    from ..psf.analytic import design_psf

    cam = CameraDesign.from_inputs(record.camera)
    return design_psf(cam, record.mode, s, size, origin="pinhole")


def robust_psf(record: CaptureRecord, size=None):
    """The speed-robust analytic PSF of a recorded capture: averaged over the design's invariant
    range (:func:`~pacam_render.psf.robust.speed_robust_psf`), registered as :func:`analytic_psf`.
    """
    from ..model.camera import CameraDesign
    from ..psf.robust import speed_robust_psf

    cam = CameraDesign.from_inputs(record.camera)
    return speed_robust_psf(cam, record.mode, size=size, origin="pinhole")
