"""A store's samples from a noise target: a pilot store, each design it is made for synthesised
from it, and the samples that bring the noisiest of them to the target.

A store's Monte Carlo variance falls as 1/spp (its passes are independent and each pixel's
samples a Latin hypercube), so the spp per pass that brings a design from the pilot's sigma
s_p to the target s_t is spp_p (s_p / s_t)^2, rounded up to the sampler's quantum. The target
is a render's (:class:`~pacam_render.exposure.estimate.AbsoluteTarget`, or
:class:`~pacam_render.sensor.apply.SensorTarget`: a ratio of a sensor's noise at the capture's
mean level), met by every design the store lists (by default its design, coded and normal).
"""

from __future__ import annotations

import math
import shutil
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .synthesis import synthesize

PILOT_SPP = 16
"""The pilot store's samples per pixel and pass."""
MAX_SPP = 65536
"""The most samples per pixel and pass a target may ask for (the disk budget refuses sooner)."""


def target_spp(render, spec, target, progress: bool = False, description=None, quantum: int = 4):
    """The spp per pass that meets ``target`` for every design ``spec`` is made for.

    Parameters
    ----------
    render : callable
        :func:`~.render.render_lightfield` (passed in: it calls this function).
    spec : StoreSpec
        The store (its ``capture.spp`` is replaced).
    target : NoiseTarget
        The Monte Carlo sigma each design's synthesised capture must reach (RMS over the
        window, the capture's units).
    quantum : int, optional
        The spp the result is a multiple of.

    Returns
    -------
    (int, list of dict)
        The spp per pass, and per design its pilot sigma, target and spp needed.
    """

    folder = Path(tempfile.mkdtemp(prefix="pacam_pilot_store."))
    try:
        pilot = replace(spec, capture=replace(spec.capture, spp=PILOT_SPP))
        store = render(pilot, folder / "store", progress=progress, truth=False,
                                  description=description)  # fmt: skip
        rows = []
        designs = spec.designs or tuple(replace(spec.capture, mode=m) for m in ("coded", "normal"))
        for d in designs:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the captures' notes are the real store's
                cap = synthesize(store, d, progress=False, description=description)
            sigma = float(np.sqrt(np.mean(cap.mc_sigma**2)))
            want = float(target.sigma(cap.image, cap.record))
            need = PILOT_SPP * (sigma / want) ** 2 if want > 0 else math.inf
            rows.append({"mode": d.mode, "design": d.design, "pilot_sigma": sigma,
                         "target_sigma": want, "spp_needed": need})  # fmt: skip
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    worst = max(r["spp_needed"] for r in rows)
    if not worst <= MAX_SPP:
        raise ParameterError(
            f"the noise target needs {worst:.3g} spp per pass for its noisiest design, over "
            f"{MAX_SPP}: raise the target, or list the designs the store is for (`designs`)"
        )
    return max(quantum, quantum * math.ceil(worst / quantum)), rows
