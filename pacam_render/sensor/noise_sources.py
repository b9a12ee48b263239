"""The sensor's random draws: the fixed pattern (PRNU gain, DSNU offset), and the per-frame
streams of shot and read noise, seeded block by block.

Seeded so that a frame depends on two seeds alone, never on the machine: the fixed pattern on
the model's ``seed`` and the sensor's shape (a spawn key of its own, so that it shares no
stream with a frame), each block of :data:`BLOCK_PIXELS` pixels on the frame's seed and the
block's index, so any number of threads gives the same bits. :class:`~.model.SensorModel`
applies the draws in its EMVA 1288 chain (the order is in its module docstring).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..errors import check_integer

BLOCK_PIXELS = 1 << 16
"""Pixels per noise block; each block has its own child SeedSequence (see module docstring)."""

_FPN_KEY = 0x46504E  # spawn-key tag of the fixed-pattern streams ("FPN")


def draw_fixed_pattern(
    seed: int, prnu: float, dsnu_e: float, shape: tuple[int, ...]
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(PRNU gain, DSNU offset in e-) maps of this shape, float32, or None where the model has
    none: the same maps for the same seed and shape, whatever the frames drawn in between."""
    ss_prnu, ss_dsnu = np.random.SeedSequence(seed, spawn_key=(_FPN_KEY, *shape)).spawn(2)
    gain = offset = None
    if prnu > 0:
        # log-normal with mean 1 and std prnu exactly
        s2 = math.log1p(prnu**2)
        z = np.random.Generator(np.random.PCG64(ss_prnu)).standard_normal(shape)
        gain = np.exp(z * math.sqrt(s2) - 0.5 * s2).astype(np.float32)
    if dsnu_e > 0:
        z = np.random.Generator(np.random.PCG64(ss_dsnu)).standard_normal(shape)
        offset = (z * dsnu_e).astype(np.float32)
    return gain, offset


def poisson_cap(full_well_e: float) -> float:
    """The largest mean electron count drawn as a Poisson count, e-.

    A mean above ``full_well_e + 40 sqrt(full_well_e) + 100`` saturates at the full well either
    way (the chance that its draw would not is below 1e-300), so it is drawn at this cap, which
    also keeps means numpy's sampler would refuse out of it.
    """
    return full_well_e + 40.0 * math.sqrt(full_well_e) + 100.0


def frame_seed(seed: int | np.random.SeedSequence | None) -> np.random.SeedSequence:
    """A fresh SeedSequence for one frame (a copy, so a reused SeedSequence repeats itself)."""
    if isinstance(seed, np.random.SeedSequence):
        return np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key)
    if seed is None:
        return np.random.SeedSequence()
    return np.random.SeedSequence(check_integer("seed", seed, 0, None))


def run_blocks(fn: Callable[[int], None], n_blocks: int, workers: int | None) -> None:
    """``fn(i)`` for every block i, on ``workers`` threads (default: all cores)."""
    if workers is None:
        n = os.cpu_count() or 1
    else:
        n = check_integer("workers", workers, 1, None)
    n = min(n, n_blocks)
    if n <= 1:
        for i in range(n_blocks):
            fn(i)
        return
    with ThreadPoolExecutor(max_workers=n) as pool:
        for _ in pool.map(fn, range(n_blocks)):
            pass
