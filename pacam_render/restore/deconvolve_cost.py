"""What a deconvolution will cost, before it runs: its peak memory and its seconds.

Every method works on the image's padded FFT grid (:func:`~.fourier.taper_pad`: the image plus
the PSF's extent on each side, rounded up to a fast FFT size), so its arrays grow with that grid
and the channels: peak bytes = fixed + grid x (shared + channels x per channel), and seconds
likewise, scaled by the iterations asked for over the method's default. The constants were
measured with ``benchmarks/bench_deconvolve_cost.py``: each method, in a fresh process, on
images of 96 x 128 to 384 x 512 px with 1 and 3 channels, peak RSS over the RSS before the call
(scipy.fft's, scikit-image's and jax's arrays included), fitted by least squares, and checked
at sizes not fitted on (320 x 240 to 1280 x 960: within 6 % of the measured peak; hl up to
4000 x 3000: -6 % to +9 %). Seconds are those of 2 cores shared with other work (the model
gave 0.6x to 2.5x the measured): a faster machine takes less, a busier one more, so the time is
an estimate ("about") and only the memory refuses work.

:func:`check_deconvolve` refuses a deconvolution whose memory is not available
(:func:`~pacam_render.limits.available_bytes`), naming the estimate, what is available and the
methods that would fit; ``deconvolve`` calls it before any work, and ``pacam deconvolve``
before it reads the capture's pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import scipy.fft as sfft

from ..errors import ParameterError
from ..limits import available_bytes, duration, gib
from .pnp import ENSEMBLE
from .pnp import ITERATIONS as PNP_ITERATIONS
from .sparse import SCHEDULE

MODEL = {
    # method: (fixed bytes, shared bytes / grid px, bytes / grid px / channel,
    #          shared s / grid px, s / grid px / channel), at the method's default iterations
    "wiener": (2e6, 50.0, 8.5, 0.0, 0.18e-6),
    "hl": (2e6, 58.0, 172.0, 4.0e-6, 1.5e-6),
    "tv": (2e6, 0.0, 255.0, 1.9e-6, 2.2e-6),
    "rl": (27e6, 66.0, 16.0, 0.0, 4.5e-6),
    "uwiener": (27e6, 131.0, 9.0, 0.0, 3.5e-6),
    "bm3d": (35e6, 704.0, 6.5, 0.0, 150e-6),
    "pnp": (300e6, 0.0, 830.0, 160e-6, 110e-6),
}
"""The constants (``benchmarks/bench_deconvolve_cost.py``), fitted on grids of 0.02 to 0.25
Mpx, 1 and 3 channels; a time or a small term whose fit came out negative is taken as 0. hl's
bytes are refitted on its measured peaks up to 4000 x 3000 px (12.4 Mpx: 525 bytes per grid px
there, 600 to 650 on the small grids; 575 fits all within -6 % to +9 %); the others' small-grid
constants overestimate a large grid alike, if anything. The fixed bytes include the packages a
method imports when it first runs (scipy.signal and scikit-image about 26 MB; jax, scico and
the network's weights 205 MB, and its compile)."""
CACHE_GRID = 3e6
"""Beyond a grid of this many px the arrays leave the caches and a px costs more time: the
seconds grow as grid^(1 + :data:`CACHE_EXPONENT`). hl took 9.4 us per grid px at 2000 x 1500
(3.1 Mpx) and 16.7 at 4000 x 3000 (12.4 Mpx; the issue's 208 s; 296 s here, niced on 2 busy
cores); its small grids took 6 to 9."""
CACHE_EXPONENT = 0.4
DEFAULT_ITERATIONS = {"hl": SCHEDULE["hl"][1], "tv": SCHEDULE["tv"][1], "rl": 30}
DEFAULT_ITERATIONS["pnp"] = PNP_ITERATIONS
"""The iterations the constants were measured at: the methods' defaults (rl's is
:func:`~.deconvolve.richardson_lucy`'s)."""
SURE_SOLVES = 11
"""``lambda_scale="sure"``: 10 solves to score the weights, then the one that is kept."""


def padded_grid(image_shape: tuple[int, ...], psf_shape: tuple[int, ...]) -> tuple[int, int]:
    """(Hp, Wp) of the FFT grid that the methods work on (:func:`~.fourier.taper_pad`)."""
    h, w = int(image_shape[0]), int(image_shape[1])
    ph, pw = int(psf_shape[0]), int(psf_shape[1])
    return (
        sfft.next_fast_len(h + 2 * ph, real=True),
        sfft.next_fast_len(w + 2 * pw, real=True),
    )


@dataclass(frozen=True)
class DeconvolveCost:
    """A deconvolution's estimated peak memory and seconds."""

    method: str
    image_shape: tuple[int, ...]
    grid: tuple[int, int]
    method_bytes: float
    """The method's own arrays at their peak, bytes."""
    input_bytes: float
    """What comes before the method: the image as float64 (and a caller's ``extra_bytes``)."""
    seconds: float
    free: float = float("nan")
    """The memory available when :func:`check_deconvolve` checked it, bytes."""

    @property
    def bytes(self) -> float:
        """Peak memory in all, bytes."""
        return self.method_bytes + self.input_bytes

    def describe(self) -> str:
        """E.g. ``about 7.4 GiB of memory and 2.3 min``."""
        return f"about {gib(self.bytes)} of memory and {duration(self.seconds)}"


def deconvolve_cost(
    image_shape: tuple[int, ...],
    psf_shape: tuple[int, ...],
    method: str,
    options: dict | None = None,
    extra_bytes: float = 0.0,
) -> DeconvolveCost:
    """The estimated peak memory and seconds of ``deconvolve(image, psf, method, **options)``.

    Parameters
    ----------
    image_shape : tuple of int
        (H, W) or (H, W, C).
    psf_shape : tuple of int
        (h, w) or (h, w, C).
    method : str
        One of :data:`MODEL`.
    options : dict, optional
        The method's keywords: ``iterations``, ``lambda_scale="sure"`` and pnp's ``ensemble``
        scale the cost.
    extra_bytes : float, optional
        Memory the caller needs besides (e.g. the other layers of the capture it reads).

    Returns
    -------
    DeconvolveCost

    Raises
    ------
    ParameterError
        If ``method`` is unknown.
    """
    if method not in MODEL:
        raise ParameterError(f"unknown `method` {method!r}; valid: {', '.join(MODEL)}")
    opts = options or {}
    channels = int(image_shape[2]) if len(image_shape) == 3 else 1
    hp, wp = padded_grid(image_shape, psf_shape)
    grid = float(hp * wp)
    fixed, shared_b, chan_b, shared_s, chan_s = MODEL[method]
    nbytes = fixed + grid * (shared_b + channels * chan_b)
    seconds = grid * (shared_s + channels * chan_s) * _work(method, opts)
    seconds *= max(1.0, grid / CACHE_GRID) ** CACHE_EXPONENT
    if opts.get("lambda_scale") == "sure":  # the probe's solve beside the image's
        nbytes += grid * channels * 16.0
    h, w = int(image_shape[0]), int(image_shape[1])
    return DeconvolveCost(
        method, tuple(image_shape), (hp, wp), nbytes, 8.0 * h * w * channels + extra_bytes, seconds
    )


def _work(method: str, opts: dict) -> float:
    """The work asked for over the work the constants were measured at."""
    factor = 1.0
    default = DEFAULT_ITERATIONS.get(method)
    if default is not None and isinstance(opts.get("iterations"), int):
        factor *= max(opts["iterations"], 1) / default
    if method in ("hl", "tv") and opts.get("lambda_scale") == "sure":
        factor *= SURE_SOLVES
    if method == "pnp" and isinstance(opts.get("ensemble"), int):
        factor *= opts["ensemble"] / ENSEMBLE
    return factor


def check_deconvolve(
    image_shape: tuple[int, ...],
    psf_shape: tuple[int, ...],
    method: str,
    options: dict | None = None,
    extra_bytes: float = 0.0,
) -> DeconvolveCost:
    """Refuse a deconvolution whose memory is not available; return its cost.

    Parameters
    ----------
    image_shape, psf_shape, method, options, extra_bytes
        As for :func:`deconvolve_cost`.

    Returns
    -------
    DeconvolveCost
        The estimate, for the caller to show.

    Raises
    ------
    ParameterError
        When the estimate exceeds :func:`~pacam_render.limits.available_bytes`: naming it (and
        its seconds), the memory available, the methods that would fit, and a smaller image.
    """
    free = available_bytes()
    cost = replace(deconvolve_cost(image_shape, psf_shape, method, options, extra_bytes), free=free)
    if cost.bytes <= free:
        return cost
    h, w = int(image_shape[0]), int(image_shape[1])
    channels = int(image_shape[2]) if len(image_shape) == 3 else 1
    fits = []
    for other in MODEL:
        if other != method:
            alt = deconvolve_cost(image_shape, psf_shape, other, None, extra_bytes)
            if alt.bytes <= free:
                fits.append(f"{other} ({gib(alt.bytes)}, {duration(alt.seconds)})")
    instead = f"`method` {' or '.join(fits[:3])} fits; " if fits else ""
    raise ParameterError(
        f"deconvolving a {w}x{h} px image of {channels} channel(s) with `method` {method} needs "
        f"{cost.describe()} (its FFT grid is {cost.grid[1]}x{cost.grid[0]} px), and "
        f"{gib(free)} is available; {instead}or deblur a smaller capture (pacam render `crop` "
        "X,Y,W,H renders a window of the sensor at full scale), or free memory"
    )
