"""The capture record: what a capture is, typed, and its JSON sidecar (``capture.json``).

A record is data, below its readers: producers of captures (:mod:`pacam_render.exposure`)
write it, and :mod:`pacam_render.sensor` (which adds the image sensor to it,
:func:`~pacam_render.sensor.apply.add_sensor_layers`), :mod:`pacam_render.restore`,
:mod:`pacam_render.study` and the CLI read it (:meth:`CaptureRecord.from_json`,
:mod:`.files`), so ``pacam render --sensor`` followed by ``pacam deconvolve`` knows the
capture's noise instead of estimating it.

The JSON keys are the ones earlier versions wrote; :meth:`CaptureRecord.from_json` also reads
the demo's older sensor block (``light_level`` for ``light_level_photons_per_px_per_ms``).
"""

from __future__ import annotations

import math
import re
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from ..errors import ParameterError
from ..limits import note
from ..model import paper
from ..model.camera import CameraDesign
from .render_error import RenderError

PIXEL_UNIT = "radiance x (open area / full aperture) x (exposure / 45 ms)"

CAPTURE_UNIT = "radiance x light_factor (a white diffuse surface reads light_factor)"
"""The unit of the layers a capture collects through its aperture and exposure."""
WHITE_UNIT = "radiance (a white diffuse surface reads 1)"
"""The unit of ``sharp``, and of every layer that :func:`read_capture` returns scaled."""
LAYER_UNITS = {
    "capture": CAPTURE_UNIT,
    "noisy": CAPTURE_UNIT,
    "mc_sigma": CAPTURE_UNIT + ", the capture's Monte Carlo sigma",
    "raw": "DN (the sensor's digital numbers)",
    "sharp": WHITE_UNIT,
    "depth": "mm (0: no surface)",
    "object_id": "1 + shape index ('objects' names it; 0: no surface)",
    "velocity": "px/ms of the capture's pixels (u right, v down)",
    "relative_illumination": "irradiance / on-axis irradiance (1 on the axis): the capture's "
    "layers are the radiance image times it",
}
"""The unit of each layer a ``capture.exr`` may hold; ``subNN`` (one pattern's image) has
``capture``'s. Layers in :data:`CAPTURE_UNIT` are divided by ``light_factor`` to be compared
with ``sharp``: :func:`read_capture` does it."""
_PATTERN_LAYER = re.compile(r"sub\d+")
EXTRA_KEYS = frozenset({"lightfield"})
"""Top-level keys of a capture.json that are not fields but are written by pacam: a capture
synthesised from a light-field store names its store."""


def layer_unit(name: str) -> str | None:
    """The unit of capture layer ``name`` (:data:`LAYER_UNITS`), or None for an unknown one."""
    return LAYER_UNITS["capture"] if _PATTERN_LAYER.fullmatch(name) else LAYER_UNITS.get(name)


@dataclass
class SensorRecord:
    """The image sensor a capture went through (:mod:`pacam_render.sensor`). Its noise sigma
    is the record's own ``noise_sigma`` (one value, in the capture's units)."""

    preset: str
    model: dict
    light_level_photons_per_px_per_ms: float | None
    photons_per_unit: float
    seed: int
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
            saturated_fraction=d.get("saturated_fraction"),
        )


@dataclass
class CaptureRecord:
    """Everything about one capture but its pixels (the ``capture.json`` sidecar).

    Units: ``exposure_ms`` and ``reference_exposure_ms`` in ms; ``light_factor`` is the
    capture's brightness relative to the full aperture over 45 ms (so ``capture /
    light_factor`` reads a white diffuse surface as about its reflectance); ``noise_sigma`` is
    the sensor's temporal noise sigma at the capture's mean level in the capture's own units
    (``noise_sigma_unit`` in the JSON says so; :attr:`noise_sigma_white_units` is it on the
    ``sharp`` layer's scale, white = 1).
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
    design_fit: dict | None = None
    """Each object against the design (:mod:`~pacam_render.exposure.design_fit`): its median
    ``depth_mm``, defocus ``r_px``, ``speed_px_per_ms`` (95th percentile), the invariant
    ``range_px_per_ms`` at its depth where the mode has one, ``off_depth`` and ``too_fast``."""
    units: dict | None = None
    """Each layer of ``capture.exr`` to its unit (:data:`LAYER_UNITS`), written with the file."""
    render_error: RenderError | None = None
    """The render's own error and its cost (:class:`~.render_error.RenderError`): ``mc_sigma``
    (RMS over the window, the capture's units), its cost and its time sampling; the sensor
    adds ``ratio_to_sensor``."""
    relative_illumination: dict | None = None
    """The sensor's relative illumination when not ``off``
    (:func:`~pacam_render.exposure.camera.illumination_record`): ``setting``, ``law``,
    the map's ``min`` and ``max``, its ``layer`` and how readers ``flat_field``."""
    optics_error: dict | None = None
    """The physics error budget (:mod:`~pacam_render.capture.optics_error`): ``diffraction``
    (its ``setting``, ``decision`` and kernels), then per effect (diffraction, relative
    illumination, the LCoS's leakage, grid and switching, bounces past ``max_depth``) whether
    it is included, how, and its size where it is left out, against the sensor's noise."""
    design: dict | None = None
    """The coded design the capture's camera was derived from, whole
    (:meth:`~pacam_render.model.camera.CameraDesign.inputs`, bitmaps included): ``psf --like``
    and ``--design CAPTURE`` rebuild it exactly. Written only where it differs from ``camera``
    (e.g. a normal capture of a coded design); None: the camera is the design."""
    extra: dict = field(default_factory=dict)
    """Keys this version does not know (kept, and written back)."""

    def to_json(self, compact: bool = True) -> dict:
        """The JSON-ready dict; optional fields that are unset are left out.

        ``compact`` (the sidecar's form) writes each value once: ``coded_design`` holds only
        the values that differ from ``optics`` (a ``normal`` or ``short`` capture's focus,
        r and a_i; nothing for a coded capture, whose camera is its design: the key is left
        out). :meth:`from_json` reads it over ``optics``, as it reads older files' full block.
        """
        out = {k: v for k, v in asdict(self).items() if k not in ("extra", "sensor")}
        if self.render_error is not None:
            out["render_error"] = self.render_error.to_json()
        if compact:
            same = self.optics
            differs = {k: v for k, v in self.coded_design.items() if k not in same or same[k] != v}
            out["coded_design"] = differs
            if not differs:
                del out["coded_design"]
        if compact and self.design == self.camera:
            out["design"] = None
        optional = ("resumed_from_step", "fastest_image_speed_px_per_ms", "noise_sigma", "design")
        optional += ("relative_illumination", "optics_error")
        for key in (*optional, "crop", "objects", "design_fit", "units", "render_error"):
            if out[key] is None:
                del out[key]
        if self.sensor is not None:
            out["sensor"] = asdict(self.sensor)
        if self.noise_sigma is not None:
            out["noise_sigma_unit"] = CAPTURE_UNIT
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
        for key in ("camera", "design"):  # every reader rebuilds them: check them here, once
            if isinstance(d.get(key), dict):
                _check_camera(d[key], f"{where}: {key}")
        _check_digest(d, where)
        kw: dict[str, Any] = {k: d[k] for k in known if k in d}
        _check_numbers(kw, where)
        kw.setdefault("light_factor", 1.0)
        kw.setdefault("exposure_ms", d["camera"].get("exposure_ms", paper.EXPOSURE_MS))
        for k in ("spec", "optics", "sensor_params", "versions"):
            kw.setdefault(k, {})
        kw["coded_design"] = {**kw["optics"], **kw.get("coded_design", {})}  # each value once
        kw.setdefault("reference_exposure_ms", paper.EXPOSURE_MS)
        kw.setdefault("render_seconds", 0.0)
        kw.setdefault("variant", "unknown")
        if isinstance(kw.get("render_error"), dict):
            kw["render_error"] = RenderError.from_json(kw["render_error"], f"{where}: render_error")
        elif kw.get("render_error") is not None:
            raise ParameterError(f"{where}: render_error must be an object")
        block = d.get("sensor")
        sensor = SensorRecord.from_json(block) if isinstance(block, dict) else None
        old = block.get("noise_sigma_white_units") if isinstance(block, dict) else None
        if kw.get("noise_sigma") is None and old is not None:  # files before one noise_sigma
            kw["noise_sigma"] = old * kw["light_factor"]
        drop = {"sensor", "noise_sigma_unit"}
        extra = {k: v for k, v in d.items() if k not in known and k not in drop}
        unknown = sorted(set(extra) - EXTRA_KEYS)
        if unknown:  # kept as they are, but said: a misspelt key would change nothing
            note(f"{where}: unknown key(s) {', '.join(map(repr, unknown[:5]))} not read (a hand "
                 "edit, or a newer pacam's record?)")  # fmt: skip
        return cls(**kw, sensor=sensor, extra=extra)

    def design_inputs(self) -> dict:
        """The coded design's inputs: :attr:`design`, else the camera (they are the same)."""
        return self.design if self.design is not None else self.camera

    @property
    def known_noise_sigma(self) -> float | None:
        """The capture's noise sigma in its own units, if a sensor model gave it."""
        return self.noise_sigma

    @property
    def noise_sigma_white_units(self) -> float | None:
        """``noise_sigma`` on the white = 1 scale of ``sharp`` (divided by ``light_factor``)."""
        if self.noise_sigma is None or not self.light_factor > 0:
            return None
        return self.noise_sigma / self.light_factor


def _check_camera(inputs: dict, where: str) -> None:
    """Refuse camera parameters no design can be built from (a hand-edited record): one line
    naming the record, where a reader would have raised a ValueError or TypeError deep in."""

    try:
        CameraDesign.from_inputs(inputs)
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from None
    except (TypeError, ValueError, OverflowError, ArithmeticError) as exc:
        raise ParameterError(f"{where}: not a camera's parameters ({exc})") from None


def _check_digest(d: dict, where: str) -> None:
    """Refuse a record whose camera no longer has the digest its ``optics`` recorded (a
    hand-edited ``camera``, whose kernels would silently be another camera's); records written
    before the digest pass."""

    optics = d.get("optics")
    recorded = optics.get("design_digest") if isinstance(optics, dict) else None
    if recorded is None:
        return
    now = CameraDesign.from_inputs(d["camera"]).digest()
    if now != recorded:
        raise ParameterError(
            f"{where}: its 'camera' was edited: its digest is {now}, where the capture recorded "
            f"{recorded} (optics.design_digest); render the capture again rather than edit it"
        )


_POSITIVE = ("light_factor", "exposure_ms", "reference_exposure_ms")
"""Record keys that must be finite numbers > 0 wherever they are given."""


def _check_numbers(kw: dict, where: str) -> None:
    """The record's scale numbers, checked once for every reader (sensor, deconvolve, study):
    a string, NaN, 0 or a negative is named here, not met later as a bad image."""
    for key in _POSITIVE:
        v = kw.get(key)
        if v is None and key not in kw:
            continue
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or v <= 0:
            raise ParameterError(f"{where}: {key} must be a finite number > 0, got {v!r}")
    sigma = kw.get("noise_sigma")
    if sigma is not None and (
        isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not sigma >= 0
        or not math.isfinite(sigma)
    ):  # fmt: skip
        raise ParameterError(f"{where}: noise_sigma must be a finite number >= 0, got {sigma!r}")


def image_size(record: CaptureRecord) -> tuple[int, int] | None:
    """(width, height) of the record's image, px: its crop's, else its sensor's; None if the
    record does not say."""
    if record.crop:
        return int(record.crop["width"]), int(record.crop["height"])
    cam = record.camera
    if "width_px" in cam and "height_px" in cam:
        return int(cam["width_px"]), int(cam["height_px"])
    return None
