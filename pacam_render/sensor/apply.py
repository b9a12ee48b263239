"""A rendered capture through the image sensor: the one place that adds ``raw`` and ``noisy``.

Both ``pacam render --sensor`` and ``pacam demo`` call :func:`add_sensor_layers`, which also
records the sensor, the light level and the noise sigma in the capture's record, so that
``pacam deconvolve`` uses the noise the capture already knows.
"""

from __future__ import annotations

import numpy as np

from ..errors import check_positive
from ..exposure.record import SensorRecord
from .model import DEFAULT_LIGHT_LEVEL, SensorModel, simulate_capture


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
    exposure = rec.exposure_ms
    if light_level is None:
        lf = rec.light_factor
        res = simulate_capture(cap.image / lf, model, exposure_ms=exposure, seed=seed)
        return res.raw_dn, res.linear * lf, res.photons_per_unit
    level = check_positive("light_level", light_level, "photons/px/ms")
    scale = rec.reference_exposure_ms / exposure  # undo the render's exposure factor ...
    res = simulate_capture(
        cap.image * scale,
        model,
        exposure_ms=exposure,
        seed=seed,
        light_level=level,
        open_area_mm2=1.0,
        reference_area_mm2=1.0,  # ... the area factor is already in it
    )
    return res.raw_dn, res.linear / scale, res.photons_per_unit


def sensor_sigma(cap, model: SensorModel, light_level: float | None, level: float) -> float:
    """Temporal noise sigma of a sensor capture at a grey ``level`` (white = 1), in the same
    white = 1 units: what a deconvolver should assume for it (Fig. 8's noise level).

    Without a light level (the ``paper`` preset) white fills the full well.
    """
    rec = cap.record
    if light_level is None:
        e_white = model.full_well_e
    else:
        e_white = model.qe * rec.light_factor * light_level * rec.reference_exposure_ms
    e = float(model.temporal_noise_e(level * e_white, rec.exposure_ms))
    return e / e_white


def add_sensor_layers(
    cap, model: SensorModel, preset: str, light_level: float | None, seed: int
) -> None:
    """Add the ``raw`` (DN) and ``noisy`` (linear) layers and record the sensor in ``cap``.

    The noiseless capture stays. A physical sensor (one with shot noise) needs photons: with
    ``light_level=None`` it gets :data:`~pacam_render.sensor.model.DEFAULT_LIGHT_LEVEL`. The
    noise sigma is taken at the noisy image's mean level.
    """
    if light_level is None and model.shot_noise:
        light_level = DEFAULT_LIGHT_LEVEL  # a physical sensor needs photons; paper does not
    raw, noisy, ppu = apply_sensor(cap, model, light_level, seed)
    rec = cap.record
    level = float(np.mean(noisy)) / rec.light_factor
    sigma = sensor_sigma(cap, model, light_level, level)
    cap.extra_layers.update({"raw": raw.astype(np.float32), "noisy": noisy})
    rec.sensor = SensorRecord(
        preset=preset,
        model=model.as_dict(),
        light_level_photons_per_px_per_ms=light_level,
        photons_per_unit=ppu,
        seed=seed,
        noise_sigma_white_units=sigma,
    )
    rec.noise_sigma = sigma * rec.light_factor  # in the capture's own units
