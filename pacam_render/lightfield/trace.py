"""Per-sample records: camera rays traced through the whole lens, their radiance kept unsummed.

Mitsuba's film adds a render's samples into pixels, which loses what a light-field store needs:
where on the lens, and when, each sample went. So the store spawns its own wavefront (the
"scripting a renderer" pattern of Mitsuba's docs): film positions, lens samples and times are
drawn in numpy from the store's seeds (the lens points from the store's proposal, :mod:`.proposal`),
the sensor turns them into rays, and the scene's integrator returns each ray's radiance. The
lens point kept is the plugin's own map of the lens sample it was given (the concentric disc of
radius R_max), so that reweighting by an aperture code uses the point the ray really left from.
"""

from __future__ import annotations

import numpy as np

CHUNK_LANES = 1 << 21
"""Rays per wavefront: about 200 MB of Dr.Jit state on 2 cores, measured fast enough."""


LD_SIZES = (4, 16, 64, 256, 1024, 4096)
"""Samples per pixel that Mitsuba's ldsampler takes as they are (square powers of two)."""
STRATA_MAX_ENTRIES = 64 * 2**20
"""The largest Latin hypercube kept (dims x pixels x samples per pass, int32): 256 MB."""


def _rng(seed: int, *words: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([seed, *words]))


class Strata:
    """Per pixel, a Latin hypercube over one pass's samples: in each of the four dimensions
    (film x, film y and the two uniforms that place the lens point) the pass's n samples of a
    pixel fall one in each of n strata, in an order drawn per pixel and dimension. The store's
    samples of one pass are spread over its time steps (one or a few per step), so this is what
    Mitsuba's low-discrepancy sampler gives a render's samples of a pixel: measured, it lowers
    the variance per sample by about the same factor (``benchmarks/bench_lightfield.py``).
    Each sample stays uniform over its dimension, so every estimate stays unbiased."""

    DIMS = 4

    def __init__(self, pixels: int, per_pass: int, seed: int, pass_index: int):
        rng = _rng(seed, pass_index, 0x5354)
        keys = rng.random((self.DIMS, pixels, per_pass), dtype=np.float32)
        self.order = np.argsort(keys, axis=2).astype(np.int32)
        self.n = per_pass

    @classmethod
    def fits(cls, pixels: int, per_pass: int) -> bool:
        return cls.DIMS * pixels * per_pass <= STRATA_MAX_ENTRIES

    def uniforms(self, pixel: np.ndarray, index: np.ndarray, rng) -> np.ndarray:
        """(4, n) uniforms for samples ``index`` (of the pass) of pixels ``pixel``."""
        jitter = rng.random((self.DIMS, len(pixel)), dtype=np.float32)
        return (self.order[:, pixel, index] + jitter) / np.float32(self.n)


def trace_records(scene, sensor, window, spp: int, seed: int, times, proposal, strata=None):
    """Trace ``spp`` samples per pixel of ``window`` and keep each one.

    Parameters
    ----------
    scene : mitsuba.Scene
        Posed as the samples' time needs (a moving scene is posed per step by the caller).
    sensor : mitsuba.Sensor
        The store's camera: the plugin with a static full opening (radius R_max).
    window : tuple of int
        (x0, y0, w, h): the sensor's film crop, px of its (enlarged) film; positions are
        drawn over it.
    spp : int
        Samples per pixel.
    seed : int
        The seed of this render (the store's seed, pass and step mixed in by the caller).
    times : float or tuple of float
        One time (ms) for every ray, or (t0, t1): uniform times over that interval.
    proposal : Proposal
        Draws each ray's lens point given its time (:mod:`.proposal`); its density is kept.
    strata : tuple of (Strata, int), optional
        The pass's Latin hypercube and the index of this render's first sample in it; None:
        independent uniforms.

    Returns
    -------
    dict of numpy.ndarray
        ``x``, ``y`` (float32, px of the window, from its corner), ``u``, ``v`` (float32, mm,
        the lens point in the plugin's local frame), ``p`` (float32, the proposal's density
        there, 1/mm^2), ``t`` (float32, ms; absent for one time) and ``L`` (float32,
        (channels, n): radiance times the sensor's weight).
    """
    x0, y0, w, h = window
    n = w * h * spp
    parts = []
    for c, start in enumerate(range(0, n, CHUNK_LANES)):
        stop = min(n, start + CHUNK_LANES)
        lanes = (start, stop)
        parts.append(_trace_chunk(scene, sensor, (w, h), spp, lanes, seed, c, times, proposal,
                                  strata))  # fmt: skip
    return {k: np.concatenate([p[k] for p in parts], axis=-1) for k in parts[0]}


def _trace_chunk(scene, sensor, size, spp, lanes, seed, chunk, times, proposal, strata):
    import drjit as dr
    import mitsuba as mi

    w, h = size
    start, stop = lanes
    n = stop - start
    rng = _rng(seed, chunk)
    lane = np.arange(start, stop, dtype=np.int64)
    pixel = lane // spp
    if strata is None:
        uni = rng.random((Strata.DIMS, n), dtype=np.float32)
    else:
        uni = strata[0].uniforms(pixel, strata[1] + lane % spp, rng)
    fx = (pixel % w + uni[0]).astype(np.float32)
    fy = (pixel // w + uni[1]).astype(np.float32)
    if isinstance(times, tuple):
        t = (times[0] + rng.random(n) * (times[1] - times[0])).astype(np.float32)
    else:
        t = np.full(n, times, np.float32)
    u, v = proposal.sample(t.astype(np.float64), rng, uni[2:].astype(np.float64))
    density = proposal.density(u, v, t.astype(np.float64)).astype(np.float32)
    radius = proposal.lens_radius_mm
    unit = mi.Point2f(mi.Float(u / radius), mi.Float(v / radius))
    lens = mi.warp.uniform_disk_to_square_concentric(unit)
    kind = "ldsampler" if spp in LD_SIZES else "independent"  # its sizes: powers of 4
    sampler = mi.load_dict({"type": kind, "sample_count": spp})
    sampler.seed(int(rng.integers(0, 2**31)), n)
    pos = mi.Point2f(mi.Float(fx / np.float32(w)), mi.Float(fy / np.float32(h)))
    ray, weight = sensor.sample_ray(mi.Float(t), mi.Float(0.5), pos, lens)
    radiance, _, _ = scene.integrator().sample(scene, sampler, ray)
    value = radiance * weight
    a = mi.warp.square_to_uniform_disk_concentric(lens) * radius  # the point the ray left from
    dr.eval(value, a)
    out = {
        "x": fx,
        "y": fy,
        "u": np.asarray(a.x, np.float32),
        "v": np.asarray(a.y, np.float32),
        "p": density,
        "L": np.asarray(value, np.float32).reshape(-1, n),  # (channels, n): rows
    }
    if isinstance(times, tuple):
        out["t"] = t
    return out
