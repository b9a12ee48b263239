"""The seconds of a capture's optics budget before it runs: the diffraction kernels and their
convolutions (issue 56: an estimate that counted only the rays was 2-9x short where a preview
builds 381 px kernels).

What a capture computes beside its rays (:mod:`.budget`, :mod:`.diffraction`,
:mod:`.wave_residual`):

* **Fraunhofer kernels**, one per colour channel (a bitmap schedule's per-window captures: one
  per distinct opening too), whenever diffraction is measured or post-processed: every lens
  capture, except one whose disc openings carry diffraction in their rays. A kernel's Fourier
  sum has L x L terms (:func:`~pacam_render.wave.fraunhofer.kernel_period_px`); kernels already
  built in this process cost nothing (:func:`.diffraction.channel_kernels` keeps them).
* **Convolutions** of the window padded by the kernel: the image (per window), its variance and
  the Monte Carlo share of the effect, for ``auto``'s preview and for the capture.
* **Exact defocused kernels** (:mod:`.wave_residual`), one per channel, where disc openings
  carry diffraction in their rays and the truth layers are rendered.

The rates are this module's constants, measured on the 2-core reference machine (the train
window 160x96, 1280x960 and 640x480 sensors, coded and normal modes):
``benchmarks/bench_cost_model.py`` prints the estimate of a render with a diffraction preview
beside its wall time.
"""

from __future__ import annotations

from ...model.modes import mode as mode_of
from ...wave.fraunhofer import DEFAULT_MAX_LOST, kernel_period_px, kernel_side_px
from ...wave.otf import fast_len, tail_px
from ...wave.patterns import channel_wavelengths_nm, mode_pupils, shows_bitmaps
from ...wave.scale import scale_for
from .budget import exact_in_rays
from .diffraction import kernels_built

KEPT_OVER_FIRST = 2.0
"""The side a disc's kernel keeps over the side first tried from its tail
(:func:`~pacam_render.wave.fraunhofer.kernel_side_px`): 2.0-2.05 measured (191 -> 381 px at
611 nm on the 1280x960 sensor, 97 -> 199 on 640x480), so the Fourier sum runs twice, at L
and at about 2L."""
KERNEL_S_PER_MTERM = 0.17
"""Seconds per million terms (L^2) of a Fraunhofer kernel's Fourier sum: 3 kernels of L = 1536
(and the first tries at 768, 720, 600) took 1.2-1.4 s; at half the sensor's scale 0.20 s."""
FFT_S_PER_MPX = 0.025
"""Seconds per million padded pixels of one channel's FFT convolution (3 channels of 160x96
with 381 px kernels: 0.05 s)."""
EXACT_S_PER_CHANNEL = 0.5
"""Seconds per channel of an exact defocused kernel against the geometric one (1.0-1.9 s for
3 channels)."""
AIRY_S_PER_CHANNEL = 0.3
"""Seconds per channel added where the rays' kernel is the disc with the Airy draw (a leaky
LCoS or a pixel grid: 1.4-2.9 s for 3 channels with the exact one)."""


def optics_seconds(plan, preview: bool, truth: bool) -> dict:
    """The predicted seconds of the optics budget's parts (name to seconds; empty for a
    pinhole), for the capture ``plan``
    (:class:`~pacam_render.exposure.plan.CapturePlan`), with ``auto``'s ``preview`` and the
    ``truth`` layers as asked. Where ``auto`` has not decided yet, the capture is taken to
    leave diffraction out (the preview's kernels serve it)."""
    spec, cam = plan.spec, plan.cam
    if not plan.lens or mode_of(spec.mode).schedule is None:
        return {}
    n = 1 if spec.grey else 3
    bitmaps = shows_bitmaps(cam, spec.mode)
    in_rays = plan.diffraction is not None and plan.diffraction[0] and not bitmaps
    in_rays = in_rays or (spec.diffraction == "on" and not bitmaps)
    out = {}
    if in_rays:
        if truth:
            per = EXACT_S_PER_CHANNEL + (0.0 if exact_in_rays(spec) else AIRY_S_PER_CHANNEL)
            out["exact kernels"] = n * per
        return out
    sides = _kernel_sides(plan, n)
    per_window = bitmaps and spec.per_pattern
    openings = len(mode_pupils(cam, spec.mode)) if per_window else 1
    if not kernels_built(cam, spec.mode, n, plan.pitch_mm, per_window):
        terms = sum(kernel_period_px(s) ** 2 + kernel_period_px(_kept(s)) ** 2 for s in sides)
        terms *= openings
        out["diffraction kernels"] = KERNEL_S_PER_MTERM * terms / 1e6
    convs = (3 if preview else 0) + (2 + (_windows(cam) if per_window else 1))
    kept = [_kept(s) for s in sides]
    out["diffraction convolutions"] = FFT_S_PER_MPX * convs * _padded_mpx(spec.image_size, kept)
    return out


def _kernel_sides(plan, n_channels: int) -> list[int]:
    """Each channel's kernel side as its Fourier sum first tries it (the opening of the
    largest tail among the schedule's)."""
    pupils = [p for p, _ in mode_pupils(plan.cam, plan.spec.mode)]
    out = []
    for wl in channel_wavelengths_nm(n_channels):
        scale = scale_for(plan.cam, wl, plan.pitch_mm)
        tail = max(tail_px(p.edge_mm, p.energy_mm2, scale) for p in pupils)
        out.append(kernel_side_px(tail, DEFAULT_MAX_LOST))
    return out


def _kept(side_px: int) -> int:
    """The side a kernel keeps: :data:`KEPT_OVER_FIRST` times the first tried, odd."""
    return int(KEPT_OVER_FIRST * (side_px // 2)) * 2 + 1


def _windows(cam) -> int:
    return int(cam.pattern_masks.array.shape[0])


def _padded_mpx(size: tuple, sides: list[int]) -> float:
    """Million pixels of each channel's padded FFT grid, summed over the channels."""
    w, h = size
    return sum(fast_len(h + 2 * s - 2) * fast_len(w + 2 * s - 2) for s in sides) / 1e6
