"""Sensor-model benchmark (issue 5): time for one 1280x960x3 frame, target < 100 ms on 2 cores.

Cases, all from the same 1280x960x3 linear render (a uniform random image) at the default light
level, F9.85, 45 ms:

- ``capture RGGB``: the prototype's colour CCD (``grasshopper-icx285``): mosaic to 1280x960,
  then the full chain (Poisson, dark current, PRNU/DSNU, read noise, clipping, ADC);
- ``simulate_capture RGGB``: the same plus the noisy linear layer (dark subtraction, bilinear
  demosaic), i.e. what ``pacam render --sensor`` will do;
- ``capture 3 planes``: the same sensor without a Bayer filter, 3 x 1280 x 960 pixels;
- ``capture paper``: the ``paper`` preset (Gaussian only), 3 planes;
- ``first frame (fixed pattern)``: a fresh model, which draws its PRNU/DSNU maps once.

Steady-state rows reuse one model (its fixed pattern is cached per shape).

    python benchmarks/bench_sensor.py [--full]
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from common import median_spread, record, timeit

from pacam_render.sensor.model import SensorModel, simulate_capture
from pacam_render.sensor.radiometry import (
    DEFAULT_LIGHT_LEVEL,
    aperture_area_mm2,
    photons_from_render,
)

H, W = 960, 1280
EXPOSURE_MS = 45.0
REF_AREA = aperture_area_mm2(1.0)
OPEN_AREA = REF_AREA * (2.8 / 9.85) ** 2


def row(case: str, fn, pixels: int, workers: int | str, repeat: int) -> dict:
    med, spread = median_spread(timeit(fn, repeat=repeat, warmup=1))
    return {
        "case": case,
        "sensor pixels": pixels,
        "workers": workers,
        "median ms": 1e3 * med,
        "± ms": 1e3 * spread,
        "ns/pixel": 1e9 * med / pixels,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="more repeats")
    repeat = 15 if ap.parse_args().full else 5
    img = np.random.default_rng(0).uniform(0.0, 1.0, (H, W, 3))
    photons = photons_from_render(img, DEFAULT_LIGHT_LEVEL, EXPOSURE_MS, OPEN_AREA, REF_AREA)
    colour = SensorModel.from_preset("grasshopper-icx285")
    mono = colour.replace(bayer=None)
    paper = SensorModel.from_preset("paper")
    unit = paper.photons_from_unit(img)
    cores = os.cpu_count() or 1

    def cap(model, p, workers=None):
        return lambda: model.capture(p, exposure_ms=EXPOSURE_MS, seed=1, workers=workers)

    def sim():
        simulate_capture(
            img,
            colour,
            exposure_ms=EXPOSURE_MS,
            seed=1,
            light_level=DEFAULT_LIGHT_LEVEL,
            open_area_mm2=OPEN_AREA,
            reference_area_mm2=REF_AREA,
        )

    def first_frame():
        SensorModel.from_preset("grasshopper-icx285").capture(
            photons, exposure_ms=EXPOSURE_MS, seed=1
        )

    rows = [
        row("capture RGGB", cap(colour, photons), H * W, cores, repeat),
        row("capture RGGB", cap(colour, photons, 1), H * W, 1, repeat),
        row("simulate_capture RGGB (+ demosaic)", sim, H * W, cores, repeat),
        row("capture 3 planes", cap(mono, photons), 3 * H * W, cores, repeat),
        row("capture 3 planes", cap(mono, photons, 1), 3 * H * W, 1, repeat),
        row("capture paper, 3 planes", cap(paper, unit), 3 * H * W, cores, repeat),
        row("first frame (fixed pattern), RGGB", first_frame, H * W, cores, max(3, repeat // 2)),
    ]
    record(
        "Sensor model: one 1280x960x3 frame (issue 5)",
        rows,
        notes="target < 100 ms on 2 cores; grasshopper-icx285 at the default light level, "
        "F9.85, 45 ms; numpy Poisson is the bulk of the time",
    )


if __name__ == "__main__":
    main()
