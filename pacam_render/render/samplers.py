"""Mitsuba's sample generators, and the sample counts each one renders as asked.

Mitsuba rounds a sampler's ``sample_count`` up to what its construction needs (checked on
3.9.1): ``ldsampler`` to a power of 4 of at least 4, ``stratified`` and ``multijitter`` to a
square, ``orthogonal`` to the square of a prime. A render of another count would take more
samples than the capture records, and one whose count does not divide Dr.Jit's block of 2^14
lanes adds a pixel's samples in a varying order (:mod:`.passes`). So each sampler renders in
chunks of the sizes in :data:`SAMPLERS`: every one is honoured exactly and keeps same-seed
renders bit-identical. ``orthogonal`` is left with 4 = 2^2, the one prime square among them.

Each seed is an independent randomisation of every sampler (``independent`` draws afresh,
the others scramble their point sets anew), so independently seeded passes estimate a
render's Monte Carlo error whatever the sampler (:mod:`pacam_render.exposure.estimate`).
"""

from __future__ import annotations

from ..errors import ParameterError

_POWERS_OF_4 = tuple(4**k for k in range(7))  # 1 .. 4096
SAMPLERS: dict[str, tuple[int, ...]] = {
    "independent": tuple(2**k for k in range(13)),
    "stratified": _POWERS_OF_4,
    "multijitter": _POWERS_OF_4,
    "orthogonal": (4,),
    "ldsampler": _POWERS_OF_4[1:],
}
"""Each sampler's render sizes (samples per pixel), smallest first; every one is a power of two
no larger than :data:`~.passes.MAX_PASS_SPP`."""
DEFAULT_SAMPLER = "ldsampler"
"""Chosen by measured efficiency 1/(sigma^2 t) on the train at full scale
(``benchmarks/bench_render_error.py``)."""


_CLASSES = {
    "IndependentSampler": "independent",
    "StratifiedSampler": "stratified",
    "MultijitterSampler": "multijitter",
    "OrthogonalSampler": "orthogonal",
    "LowDiscrepancySampler": "ldsampler",
}


def sampler_name(sampler) -> str:
    """The plugin name of a loaded ``mi.Sampler`` (``independent`` for one not listed here:
    powers of two are what Mitsuba's other samplers take too)."""
    return _CLASSES.get(sampler.class_name(), "independent")


def check_sampler(name: str) -> str:
    """``name`` if Mitsuba's sampler of that name is supported, else ParameterError."""
    if name not in SAMPLERS:
        raise ParameterError(f"sampler must be one of {', '.join(SAMPLERS)}, got {name!r}")
    return name


def quantum(name: str) -> int:
    """The smallest render of sampler ``name``, spp: every sample count is a multiple of it."""
    return SAMPLERS[check_sampler(name)][0]


def round_spp(spp: int, name: str) -> int:
    """``spp`` rounded up to a multiple of the sampler's :func:`quantum` (at least one)."""
    q = quantum(name)
    return max(q, -(-int(spp) // q) * q)


def sampler_dict(name: str, spp: int) -> dict:
    """The ``mi.load_dict`` entry of sampler ``name`` with ``spp`` samples per pixel."""
    return {"type": check_sampler(name), "sample_count": int(spp)}
