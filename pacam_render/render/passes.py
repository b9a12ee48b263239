"""Sample passes: one film render split so that the same seed gives the same bits.

Mitsuba's wavefront renderer lays out a pixel's samples next to each other and adds them to the
film with atomic scatter-adds, while Dr.Jit's LLVM backend runs the wavefront in blocks of
2^14 lanes on several threads. When ``spp`` does not divide the block size, some pixels' samples
fall in two blocks, two threads add to that pixel in an order that varies from run to run, and
the float32 sum differs by an ulp (measured: 18 to 37 of 19 200 pixels at 300 spp, 0 at 256).
A chunk whose spp is a power of two no larger than :data:`MAX_PASS_SPP` keeps every pixel
inside one block, so it is deterministic. :func:`split_spp` writes any spp as such chunks (its
binary digits, or the sizes a sampler renders exactly, :mod:`.samplers`), which also keeps a
chunk below Mitsuba's limit of 2^32 samples per wavefront; and at most
:data:`MAX_CHUNK_SAMPLES` samples where it can, so that a signal is answered within
seconds. (These chunks are one render's parts; the independent passes whose spread measures
a capture's Monte Carlo error are :mod:`pacam_render.exposure.estimate`'s.)
"""

from __future__ import annotations

import numpy as np

from .samplers import SAMPLERS, check_sampler, sampler_name

MAX_PASS_SPP = 1 << 12
"""The largest pass: a power of two that divides Dr.Jit's LLVM block (2^14 lanes)."""
MAX_WAVEFRONT = 1 << 31
"""The most samples one pass may hold (Mitsuba refuses 2^32 and more)."""
MAX_CHUNK_SAMPLES = 1 << 26
"""The most samples a chunk holds where one sample per pixel allows it: a signal (SIGTERM,
which Python answers only between ``mi.render`` calls) waits for the chunk in flight, about
5 s at this size on the 2-core reference machine (0.072 s per million samples). A 1280x960
film took 1024 spp chunks before, 90 s each, and a SIGTERM was answered 150 s late."""


def split_spp(spp: int, pixels: int, sampler: str = "independent") -> list[int]:
    """Chunk sizes that sum to ``spp``, largest first, each under the wavefront limit.

    Parameters
    ----------
    spp : int
        Samples per pixel, >= 1; a multiple of the sampler's smallest size
        (:func:`~.samplers.quantum`).
    pixels : int
        Film pixels (width x height), >= 1.
    sampler : str, optional
        Mitsuba's sampler: the chunks are sizes it renders exactly (:data:`~.samplers.SAMPLERS`).

    Returns
    -------
    list of int
        Chunk sizes, each a power of two <= min(:data:`MAX_PASS_SPP`,
        :data:`MAX_CHUNK_SAMPLES` / pixels), or 1 spp where that is less than one.

    Raises
    ------
    ValueError
        If one sample per pixel already exceeds :data:`MAX_WAVEFRONT`, or ``spp`` is not a
        multiple of the sampler's smallest size.
    """

    if pixels > MAX_WAVEFRONT:
        raise ValueError(f"{pixels} pixels exceed one wavefront ({MAX_WAVEFRONT} samples)")
    cap = min(MAX_PASS_SPP, 1 << max(0, (MAX_CHUNK_SAMPLES // pixels).bit_length() - 1))
    sizes = [n for n in SAMPLERS[check_sampler(sampler)] if n <= cap][::-1]
    if not sizes or int(spp) % sizes[-1]:
        raise ValueError(f"{sampler} cannot render {spp} spp over {pixels} pixels exactly")
    out, rest = [], int(spp)
    for n in sizes:  # greedy: each size divides the larger ones
        out += [n] * (rest // n)
        rest %= n
    return out


def pass_seed(seed: int, index: int) -> int:
    """The seed of pass ``index`` > 0 of a render seeded ``seed`` (pass 0 uses ``seed``)."""
    return int(np.random.SeedSequence([seed, 1 << 20, index]).generate_state(1)[0] >> 1)


def render_passes(
    scene, spp: int, seed: int, stop=None, sensor=None, integrator=None, on_cut=None
) -> np.ndarray | None:
    """``mi.render(scene, spp, seed)``, deterministically: the mean of :func:`split_spp` passes.

    Parameters
    ----------
    scene : mitsuba.Scene
    spp : int
        Samples per pixel of the whole render: a multiple of the sensor's sampler's smallest
        render (:func:`~.samplers.quantum`).
    seed : int
        The first pass's seed; the others get :func:`pass_seed`.
    stop : callable, optional
        Asked after each chunk: True abandons the render.
    sensor, integrator : mitsuba objects, optional
        Render through these instead of the scene's own (``mi.render``'s arguments).
    on_cut : callable, optional
        Called when Mitsuba cut a chunk short: on SIGINT during ``mi.render`` its own handler
        cancels the render and returns what it has, and Python's handler never runs. The
        integrator's ``should_stop()`` says so afterwards; the render is then abandoned (a
        partial chunk is never used) and ``on_cut`` told, so the caller knows of the signal.

    Returns
    -------
    numpy.ndarray or None
        The film image, float64, weighted by each pass's share of the samples: (H, W, C), or
        (H, W) for a one-channel (luminance or mono) film, the shape a grey layer has when read
        back from an EXR; None when ``stop`` abandoned it.
    """
    import mitsuba as mi

    sensor = scene.sensors()[0] if sensor is None else sensor
    film = sensor.film()
    w, h = (int(v) for v in film.crop_size())
    passes = split_spp(spp, w * h, sampler_name(sensor.sampler()))
    integ = scene.integrator() if integrator is None else integrator
    attach = getattr(sensor, "set_probe_scene", None)  # the exact PSF's depth probe
    if attach is not None:
        attach(scene)
    try:
        acc = 0.0
        for i, n in enumerate(passes):
            s = seed if i == 0 else pass_seed(seed, i)
            image = np.array(
                mi.render(scene, sensor=sensor, integrator=integrator, spp=n, seed=s),
                dtype=np.float64,
            )
            if image.ndim == 3 and image.shape[2] == 1:  # a grey film: (H, W), as EXR reads it
                image = image[..., 0]
            if integ.should_stop():  # Mitsuba took a SIGINT: this chunk is partial
                if on_cut is not None:
                    on_cut()
                return None
            if stop is not None and stop():
                return None
            acc = image if len(passes) == 1 else acc + n * image
    finally:
        if attach is not None:
            attach(None)  # no scene -> sensor -> scene cycle outlives the render
    return acc if len(passes) == 1 else acc / spp
