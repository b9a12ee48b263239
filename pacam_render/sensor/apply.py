"""A rendered capture through the image sensor: the one place that adds ``raw`` and ``noisy``.

Both ``pacam render --sensor`` and ``pacam demo`` call :func:`add_sensor_layers`, which also
records the sensor, the light level and the noise sigma in the capture's record, so that
``pacam deconvolve`` uses the noise the capture already knows.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ..capture.optics_error import add_ratios
from ..capture.record import SensorRecord
from ..errors import ParameterError, check_positive
from ..limits import PacamWarning
from .model import SensorModel, simulate_capture
from .presets import mono_preset
from .radiometry import DEFAULT_LIGHT_LEVEL, check_light_level

SATURATION_NOTE = 1e-3
"""A capture with more than this fraction of saturated values gets a note."""


def apply_sensor(cap, model: SensorModel, light_level: float | None, seed: int):
    """Raw DN and the noisy linear image (in the capture's units) of a capture.

    Parameters
    ----------
    cap : Capture
    model : SensorModel
    light_level : float or None
        Photons/px/ms that a white diffuse surface delivers through the full aperture. The
        render already carries the open-area and exposure factors relative to the full
        aperture and 45 ms, so photons = value x light_level x 45 ms. None (the ``paper``
        preset): the capture is first divided by its light factor, so that white reads 1.0
        and the noise sigma is relative to white, as in the paper.
    seed : int

    Returns
    -------
    raw_dn, noisy, photons_per_unit : numpy.ndarray, numpy.ndarray, float
    """
    rec = cap.record
    image, back = _sensor_input(cap, light_level)
    if light_level is None:
        res = simulate_capture(image, model, exposure_ms=rec.exposure_ms, seed=seed)
        return res.raw_dn, res.linear * back, res.photons_per_unit
    level = check_light_level(light_level)
    res = simulate_capture(
        image,
        model,
        exposure_ms=rec.exposure_ms,
        seed=seed,
        light_level=level,
        open_area_mm2=1.0,
        reference_area_mm2=1.0,  # the render already carries the area factor
    )
    return res.raw_dn, res.linear * back, res.photons_per_unit


def units_per_input(rec, light_level: float | None) -> float:
    """The capture's (and noisy layer's) units per unit of the sensor's input: the light factor
    without a light level (white reads 1.0); with one, the render's exposure factor."""
    if light_level is None:
        return rec.light_factor
    return 1.0 / (rec.reference_exposure_ms / rec.exposure_ms)  # as the input's inverse


def _sensor_input(cap, light_level: float | None) -> tuple[np.ndarray, float]:
    """The render in the units :func:`simulate_capture` takes, and the factor back to the
    capture's units: divided by the light factor without a light level (white reads 1.0);
    with one, the render's exposure factor undone (the area factor stays in it)."""
    rec = cap.record
    back = units_per_input(rec, light_level)
    if light_level is None:
        return cap.image / back, back
    return cap.image * (rec.reference_exposure_ms / rec.exposure_ms), back


def saturated_fraction(cap, model: SensorModel, light_level: float | None, ppu: float) -> float:
    """The fraction of the capture's values whose mean charge exceeds the sensor's saturation
    (full well or ADC range, :attr:`SensorModel.saturation_e`), before noise.

    Parameters
    ----------
    cap : Capture
    model : SensorModel
    light_level : float or None
        As for :func:`apply_sensor`.
    ppu : float
        Photons per pixel for 1.0 of the sensor's input (:func:`apply_sensor`'s third value).

    Returns
    -------
    float
        In [0, 1], over every pixel and colour channel.
    """
    image, _ = _sensor_input(cap, light_level)
    return float(np.mean(model.qe * ppu * image > model.saturation_e))


def sensor_sigma(rec, model: SensorModel, light_level: float | None, level: float) -> float:
    """Temporal noise sigma of a capture (its record ``rec``) through the sensor at a grey
    ``level`` (white = 1), in the same white = 1 units: what a deconvolver should assume for
    it (Fig. 8's noise level).

    Without a light level (the ``paper`` preset) white fills the full well.
    """
    if light_level is None:
        e_white = model.full_well_e
    else:
        e_white = model.qe * rec.light_factor * light_level * rec.reference_exposure_ms
    e = float(model.temporal_noise_e(level * e_white, rec.exposure_ms))
    return e / e_white


def clean_level(cap) -> float:
    """The capture's mean grey level (white = 1) that its sensor noise is taken at: the
    noise-free capture's, as the noisy layer's mean less the sensor's offset and read noise can
    be negative at low light (and is the same level plus noise otherwise). In float32, as the
    capture is written, so that a capture read back gives the same sigma."""
    mean = float(np.mean(np.asarray(cap.image, dtype=np.float32), dtype=np.float64))
    return max(0.0, mean) / cap.record.light_factor


def add_sensor_layers(
    cap, model: SensorModel, preset: str, light_level: float | None, seed: int
) -> None:
    """Add the ``raw`` (DN) and ``noisy`` (linear) layers and record the sensor in ``cap``.

    The noiseless capture stays. A physical sensor (one with shot noise) needs photons: with
    ``light_level=None`` it gets :data:`~pacam_render.sensor.radiometry.DEFAULT_LIGHT_LEVEL`. The
    noise sigma is taken at the noise-free capture's mean level.

    Raises
    ------
    ParameterError
        If the capture is grey (one channel) and the sensor has a Bayer filter: a grey image is
        not a mosaic (:func:`check_grey_sensor`).
    """
    check_grey_sensor(is_grey(cap.image), model, preset)
    light_level = _light_level(model, light_level)
    raw, noisy, ppu = apply_sensor(cap, model, light_level, seed)
    saturated = saturated_fraction(cap, model, light_level, ppu)
    rec = cap.record
    if saturated > SATURATION_NOTE:
        note = (
            f"{100 * saturated:.3g} % of the pixel values saturate the sensor (above "
            f"{model.saturation_e:.4g} e-); lower the light level (light_level)"
        )
        warnings.warn(note, PacamWarning, stacklevel=2)
        rec.notes.append(note)
    sigma = sensor_sigma(rec, model, light_level, clean_level(cap))
    cap.extra_layers.update({"raw": raw.astype(np.float32), "noisy": noisy})
    rec.sensor = SensorRecord(
        preset=preset,
        model=model.as_dict(),
        light_level_photons_per_px_per_ms=light_level,
        photons_per_unit=ppu,
        seed=seed,
        saturated_fraction=saturated,
    )
    rec.noise_sigma = sigma * rec.light_factor  # in the capture's own units
    if rec.render_error is not None and rec.noise_sigma > 0:
        rec.render_error.ratio_to_sensor = rec.render_error.mc_sigma / rec.noise_sigma
    if rec.optics_error is not None:  # the budget against this sensor, not a stand-in
        where = preset + (f" at {light_level:g} photons/px/ms" if light_level else "")
        add_ratios(rec.optics_error, rec.noise_sigma, where)


def is_grey(image: np.ndarray) -> bool:
    """Whether a capture's image is grey: (H, W), or (H, W, 1).

    Parameters
    ----------
    image : numpy.ndarray
        The capture's image.

    Returns
    -------
    bool
        True for one channel.
    """
    shape = np.shape(image)
    return len(shape) == 2 or (len(shape) == 3 and shape[2] == 1)


def check_grey_sensor(grey: bool, model: SensorModel, preset: str) -> None:
    """Refuse a colour-filter (Bayer) sensor on a grey capture, and a monochrome one (a
    physical sensor with no colour filter) on an RGB capture.

    Parameters
    ----------
    grey : bool
        The capture is grey (:func:`is_grey`), or will be
        (:func:`~pacam_render.render.variant.grey_request`).
    model : SensorModel
        The sensor.
    preset : str
        Its name, for the message.

    Raises
    ------
    ParameterError
        If ``grey`` and ``model.bayer`` is set: the sensor would take the grey image
        for a raw mosaic and demosaic it into false colour. The message names the monochrome
        preset to use (:func:`~pacam_render.sensor.presets.mono_preset`). If not ``grey``
        and the sensor is monochrome: its noise would be drawn per channel.
    """
    if not grey and model.bayer is None and model.shot_noise:
        raise ParameterError(
            f"`sensor` {preset} is monochrome (no colour filter), but the capture is RGB: its "
            "noise model would be applied to each channel as if each were the whole sensor; "
            "render the capture grey (`grey=True`), or pick a colour sensor"
        )
    if model.bayer is None or not grey:
        return
    mono = mono_preset(preset)
    use = (
        f"use its monochrome twin, `sensor` {mono}"
        if mono != preset
        else "use grasshopper-icx285-mono, or a preset file with no bayer key"
    )
    raise ParameterError(
        f"`sensor` {preset} has a colour filter array ({model.bayer} Bayer), but the capture "
        f"is grey (one channel: rendered with `grey=True` or a mono variant); {use}"
    )


def _light_level(model: SensorModel, light_level: float | None) -> float | None:
    """A physical sensor (one with shot noise) needs photons: without a light level it gets
    :data:`~pacam_render.sensor.radiometry.DEFAULT_LIGHT_LEVEL`; the ``paper`` preset needs none."""
    if light_level is None and model.shot_noise:
        return DEFAULT_LIGHT_LEVEL
    return light_level


@dataclass(frozen=True)
class SensorTarget:
    """A noise target for a render: ``ratio`` times the sensor's temporal noise at the
    capture's mean level (:func:`sensor_sigma`), in the capture's units; with several
    ``sensors`` ((preset, light level) pairs, the light level None for the preset's default),
    ``ratio`` times the lowest of their noises, so that the render adds at most ``ratio^2`` to
    the noise variance of every one (:class:`~pacam_render.exposure.estimate.NoiseTarget`).
    """

    ratio: float
    sensors: tuple[tuple[str, float | None], ...]

    def __post_init__(self) -> None:
        check_positive("noise_ratio", self.ratio)
        if not self.sensors:
            raise ParameterError("noise_ratio needs a sensor (its noise is what it scales)")
        for preset, level in self.sensors:
            SensorModel.from_preset(preset)  # raises, naming the presets
            if level is not None:
                check_light_level(level)

    def sensor_sigmas(self, mean_image: np.ndarray, rec) -> list[float]:
        """Each sensor's noise sigma at the image's mean level, the capture's units."""
        lf = rec.light_factor
        level = float(np.mean(mean_image)) / lf if lf > 0 else 0.0
        out = []
        for preset, light in self.sensors:
            model = SensorModel.from_preset(preset)
            out.append(sensor_sigma(rec, model, _light_level(model, light), level) * lf)
        return out

    def sigma(self, mean_image: np.ndarray, rec) -> float:
        return self.ratio * min(self.sensor_sigmas(mean_image, rec))

    def to_json(self) -> dict:
        return {"kind": "sensor", "ratio": self.ratio, "sensors": [list(s) for s in self.sensors]}
