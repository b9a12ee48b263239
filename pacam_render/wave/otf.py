"""The optical transfer function of a pupil: the autocorrelation of its field.

The incoherent PSF is |FT(P)|^2, so its Fourier transform, the OTF, is the pupil's normalised
autocorrelation (Goodman, *Introduction to Fourier Optics*, 3rd ed., Eq. 6-28):

    H(nu) = int P(x) P*(x + lambda D nu) dx  /  int |P|^2 dx,

with nu in cycles/mm of the image and D the pupil distance (:mod:`.scale`). It vanishes
beyond the pupil's own width, so a kernel can be summed from it exactly (:mod:`.fraunhofer`).

- A disc has the closed form of :func:`~pacam_render.wave.reference.circular_mtf`.
- A :class:`~pacam_render.wave.pupil.GridPupil` of uniform square cells has, at lags that are
  whole cells, exactly the discrete autocorrelation of its amplitudes, and between them the
  bilinear interpolation of those values: the autocorrelation of one square is the product of
  two triangles, which is what bilinear interpolation is. So its OTF is exact everywhere.

Every OTF here also states its PSF's tail: the energy outside a box of half-width h px is
~ c / h, with c = E lambda D / (2 pi^2 A p), E the pupil's edge length and A its area (for a
disc, 2 lambda N / (pi^2 p): the asymptote 2 / (pi v) of Rayleigh's encircled energy, Born &
Wolf 8.5.2 Eq. 20). Kernel sizes are chosen from it before anything is computed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .pupil import DiscPupil, GridPupil
from .reference import circular_mtf
from .scale import DiffractionScale


def fast_len(n: int) -> int:
    """The smallest m >= n whose only prime factors are 2, 3 and 5 (a fast FFT length)."""
    m = max(1, int(n))
    while True:
        k = m
        for p in (2, 3, 5):
            while k % p == 0:
                k //= p
        if k == 1:
            return m
        m += 1


@dataclass(frozen=True)
class OTF:
    """A normalised OTF on the image's pixel grid (frequencies in cycles/px).

    Attributes
    ----------
    grid : callable
        ``grid(nu_x, nu_y) -> array (len(nu_y), len(nu_x))``: H on the tensor grid; H(0) = 1,
        H(-nu) = conj(H(nu)).
    cutoff_x, cutoff_y : float
        H = 0 where |nu_x| >= cutoff_x or |nu_y| >= cutoff_y, cycles/px.
    tail_px : float
        c of the PSF's energy outside a box of half-width h px, ~ c / h (module docstring).
    """

    grid: Callable[[np.ndarray, np.ndarray], np.ndarray]
    cutoff_x: float
    cutoff_y: float
    tail_px: float


def tail_px(edge_mm: float, energy_mm2: float, scale: DiffractionScale) -> float:
    """c = E lambda D / (2 pi^2 A p), px: the PSF's energy outside a box of half-width h px is
    ~ c / h (module docstring)."""
    lam_d = scale.wavelength_mm * scale.pupil_distance_mm
    return edge_mm * lam_d / (2.0 * math.pi**2 * energy_mm2 * scale.pixel_pitch_mm)


def radial_otf(fn, cutoff: float, tail: float) -> OTF:
    """An OTF that depends on |nu| only: ``fn(rho_cycles_per_px)``, 0 beyond ``cutoff``."""

    def grid(nu_x, nu_y):
        return fn(np.hypot(np.asarray(nu_y)[:, None], np.asarray(nu_x)[None, :]))

    return OTF(grid, float(cutoff), float(cutoff), float(tail))


def disc_otf(pupil: DiscPupil, scale: DiffractionScale) -> OTF:
    """The closed-form OTF of a disc (Goodman Eq. 6-32)."""
    ln = scale.lambda_n_px(pupil.radius_mm)
    tail = tail_px(pupil.edge_mm, pupil.energy_mm2, scale)
    return radial_otf(lambda rho: circular_mtf(rho, ln), 1.0 / ln, tail)


def autocorrelation(amplitude: np.ndarray) -> np.ndarray:
    """The normalised discrete autocorrelation C[d] = sum_x a[x + d] conj(a[x]) / sum |a|^2,
    centred (d = 0 at index (H, W) of the (2H+1, 2W+1) result), by zero-padded FFTs."""
    h, w = amplitude.shape
    shape = (fast_len(2 * h + 1), fast_len(2 * w + 1))  # no wrap-around: lags reach h - 1
    if np.iscomplexobj(amplitude):
        F = np.fft.fft2(amplitude, shape)
        c = np.fft.ifft2(F * np.conj(F))
    else:
        F = np.fft.rfft2(amplitude, shape)
        c = np.fft.irfft2(F * np.conj(F), shape)
    c = np.roll(c, (h, w), axis=(0, 1))[: 2 * h + 1, : 2 * w + 1]
    return c / c[h, w].real


def _bilinear(pos: np.ndarray, n: int):
    """Left index, fraction and validity of positions on a grid of n samples."""
    i0 = np.floor(pos).astype(np.int64)
    ok = (i0 >= 0) & (i0 <= n - 2)
    return np.clip(i0, 0, max(n - 2, 0)), pos - i0, ok


def grid_otf(pupil: GridPupil, scale: DiffractionScale) -> OTF:
    """The exact OTF of a pupil of uniform square cells (module docstring).

    The lag that an image frequency nu (cycles/px) probes is -nu lambda D / p mm, i.e.
    -nu lambda D / (p dx) cells for cells of side dx.
    """
    c = _real_autocorrelation(pupil.amplitude)
    tail = tail_px(pupil.edge_mm, pupil.energy_mm2, scale)
    return _lag_otf(c, pupil.pitch_mm, scale, tail)


def mixture_otf(parts, scale: DiffractionScale) -> OTF:
    """The OTF of a light-weighted mixture of pupils of one cell pitch: sum w_k H_k / sum w_k,
    exact (each H_k is translation-invariant, so the normalised autocorrelations add on one
    array of lags). Its kernel is the weighted mean of the pupils' kernels, computed once: a
    bitmap schedule's 64 patterns took 64 kernels per wavelength.

    Parameters
    ----------
    parts : list of (GridPupil, float)
        The pupils (one ``pitch_mm``) and their weights (> 0).
    scale : DiffractionScale
    """
    pitches = {p.pitch_mm for p, _ in parts}
    if len(pitches) != 1:
        raise ParameterError(f"a mixture's pupils must share one cell pitch, got {pitches}")
    cs = [(_real_autocorrelation(p.amplitude), float(w)) for p, w in parts]
    H = max(c.shape[0] for c, _ in cs) // 2
    W = max(c.shape[1] for c, _ in cs) // 2
    acc = np.zeros((2 * H + 1, 2 * W + 1), dtype=np.result_type(*(c for c, _ in cs)))
    for c, w in cs:
        h, wd = c.shape[0] // 2, c.shape[1] // 2
        acc[H - h : H + h + 1, W - wd : W + wd + 1] += w * c
    total = sum(w for _, w in cs)
    tail = sum(w * tail_px(p.edge_mm, p.energy_mm2, scale) for p, w in parts) / total
    return _lag_otf(acc / total, pitches.pop(), scale, tail)


def _real_autocorrelation(a: np.ndarray) -> np.ndarray:
    c = autocorrelation(a)
    return c if np.iscomplexobj(a) else c.real


def _lag_otf(c: np.ndarray, pitch_mm: float, scale: DiffractionScale, tail: float) -> OTF:
    """The OTF whose value at nu is the lag array ``c`` (centred, H(0) = 1) read bilinearly at
    -nu lambda D / p, in cells of ``pitch_mm``; 0 beyond the array."""
    h, w = c.shape[0] // 2, c.shape[1] // 2
    cells_per_cycle = scale.lag_mm_per_cycle_per_px / pitch_mm

    def grid(nu_x, nu_y):
        ix, fx, okx = _bilinear(w - np.asarray(nu_x, float) * cells_per_cycle, 2 * w + 1)
        iy, fy, oky = _bilinear(h - np.asarray(nu_y, float) * cells_per_cycle, 2 * h + 1)
        cx = c[:, ix] * (1.0 - fx) + c[:, ix + 1] * fx
        cx[:, ~okx] = 0.0
        out = cx[iy] * (1.0 - fy)[:, None] + cx[iy + 1] * fy[:, None]
        out[~oky] = 0.0
        return out

    return OTF(grid, w / cells_per_cycle, h / cells_per_cycle, tail)


def grid_cutoffs(pupil: GridPupil, scale: DiffractionScale) -> tuple[float, float]:
    """(cutoff_x, cutoff_y), cycles/px, of a :class:`GridPupil`'s OTF: the array's width and
    height in cells over the cells one cycle/px probes (no autocorrelation needed)."""
    h, w = pupil.amplitude.shape
    cells_per_cycle = scale.lag_mm_per_cycle_per_px / pupil.pitch_mm
    return w / cells_per_cycle, h / cells_per_cycle


def pupil_cutoff(pupil, scale: DiffractionScale) -> float:
    """The highest image frequency (cycles/px, along either axis) a pupil passes."""
    if isinstance(pupil, DiscPupil):
        return scale.cutoff_cycles_per_px(pupil.radius_mm)
    if isinstance(pupil, GridPupil):
        return max(grid_cutoffs(pupil, scale))
    raise TypeError(f"pupil must be a DiscPupil or a GridPupil, got {type(pupil).__name__}")


def pupil_otf(pupil, scale: DiffractionScale) -> OTF:
    """The OTF of a :class:`DiscPupil` (closed form) or a :class:`GridPupil` (exact)."""
    if isinstance(pupil, DiscPupil):
        return disc_otf(pupil, scale)
    if isinstance(pupil, GridPupil):
        return grid_otf(pupil, scale)
    raise TypeError(f"pupil must be a DiscPupil or a GridPupil, got {type(pupil).__name__}")
