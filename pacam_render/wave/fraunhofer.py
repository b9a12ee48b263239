"""The Fraunhofer PSF of a pupil on the sensor's pixel grid: |FT(pupil)|^2, pixel-integrated.

Method (no pupil sampling, no quadrature). The kernel is summed from the pupil's OTF H
(:mod:`.otf`), which vanishes beyond the pupil's width. A pixel-integrated PSF is the PSF
convolved with the pixel's box, so its transform is H(nu) sinc(nu_x) sinc(nu_y), and by
Poisson's summation formula the Fourier series on frequencies spaced 1/L,

    k_L(m) = L^-2 sum_{nu in Z^2 / L} H(nu) sinc(nu_x) sinc(nu_y) exp(2 pi i nu . m),

is exactly sum_j k(m + j L): the kernel repeated with period L px. One inverse FFT of size
L x L, after folding the finitely many non-zero terms modulo 1 cycle/px, gives every pixel.
Two errors remain, both stated on every kernel (:class:`DiffractionKernel`):

- truncation (``lost``): the light outside the odd ``size`` x ``size`` kernel, measured
  exactly from the periodic sum (whose total is H(0) = 1). The kernel is renormalised, so its
  L1 error from this is 2 ``lost``. The PSF's tail falls only as c / h (:mod:`.otf`: at F9.85
  and 550 nm c = 0.17 px, so 1 % of the light lies beyond a 31 px box, 0.2 % beyond 153 px
  and 0.1 % beyond 305 px): ``size`` is the smallest that loses at most ``max_lost``.
- aliasing (``alias``): what the copies at j != 0 add inside the kernel, at most the energy
  beyond a box of half-width L - h, ~ c / (L - h) with c measured from ``lost``. The period is
  L >= 4 x size, so ``alias`` <= ``lost`` / 7.

``sampling="band"`` keeps instead the frequencies |nu_x|, |nu_y| <= 1/2 without the pixel's
sinc: the discrete filter whose transfer function is exactly H on the pixel grid's band (for
convolving rendered images, whose pixels already integrate; it has small negative lobes).

Error against run time (one shared core, 550 nm): see ``benchmarks/bench_diffraction.py``.
The disc at F9.85 against the Airy pattern integrated by Gauss-Legendre quadrature
(:func:`~pacam_render.wave.reference.airy_kernel_quadrature`): L1 < 1e-6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError, check_range
from ..limits import check_memory
from .otf import OTF, fast_len, pupil_otf
from .scale import DiffractionScale

DEFAULT_MAX_LOST = 0.002
"""Default bound on the diffracted light a kernel may leave out (its L1 error is twice this):
a 153 px kernel at F9.85, 45 px at F2.8 (550 nm). ``benchmarks/RESULTS.md`` ("Diffraction
kernels") gives the image-level effect of the truncation against its cost."""
MAX_KERNEL_PX = 2049
"""Largest kernel side, px (as :data:`pacam_render.psf.grid.MAX_AUTO_SIZE`)."""
MAX_PERIOD_PX = 4320
"""Largest period L of the Fourier sum, px (a 4320^2 complex FFT, 300 MB): at least
2 x :data:`MAX_KERNEL_PX` + 1, so that every kernel fits in one period."""
MAX_OTF_SAMPLES = 2**26
"""Most OTF values summed for one kernel (~10 s); more means a very fast pupil at a large
period, which a smaller ``size`` avoids."""
SAMPLINGS = ("pixel", "band")


@dataclass(frozen=True, eq=False)
class DiffractionKernel:
    """A diffraction kernel and its stated errors.

    Attributes
    ----------
    kernel : numpy.ndarray
        Odd square, centred on the point's image, summing to 1.
    lost : float
        Fraction of the PSF's light outside the kernel (renormalised away).
    alias : float
        Estimated light the period's copies add inside the kernel (an upper estimate).
    period_px : int
        The period L of the Fourier sum.
    sampling : str
        ``"pixel"`` (each value is the PSF integrated over the pixel) or ``"band"``.
    """

    kernel: np.ndarray
    lost: float
    alias: float
    period_px: int
    sampling: str

    @property
    def l1_bound(self) -> float:
        """An estimate of the kernel's L1 error: 2 (lost + alias)."""
        return 2.0 * (self.lost + self.alias)


def _weights(nu: np.ndarray, sampling: str) -> np.ndarray:
    if sampling == "pixel":
        return np.sinc(nu)  # the pixel's box, one axis
    w = (np.abs(nu) < 0.5).astype(float)
    w[np.isclose(np.abs(nu), 0.5, rtol=0, atol=1e-12)] = 0.5  # the band's edge, shared
    return w


def _fold_index(n: int, L: int) -> list[tuple[slice, np.ndarray]]:
    """Chunks of the 2n + 1 frequencies -n..n whose indices modulo L are distinct."""
    k = np.arange(-n, n + 1)
    return [(slice(i, min(i + L, k.size)), k[i : i + L] % L) for i in range(0, k.size, L)]


def _half_count(cutoff: float, L: int, sampling: str) -> int:
    c = min(cutoff, 0.5) if sampling == "band" else cutoff
    return int(math.ceil(c * L))


def periodic_kernel(otf: OTF, period_px: int, sampling: str = "pixel") -> np.ndarray:
    """The L x L periodic sum k_L of the module docstring, centred at (L//2, L//2).

    Parameters
    ----------
    otf : OTF
    period_px : int
        L, px.
    sampling : {"pixel", "band"}

    Returns
    -------
    numpy.ndarray
        float64 (L, L); its sum is H(0) = 1.
    """
    L = int(period_px)
    nx = _half_count(otf.cutoff_x, L, sampling)
    ny = _half_count(otf.cutoff_y, L, sampling)
    if (2 * nx + 1) * (2 * ny + 1) > MAX_OTF_SAMPLES:
        raise ParameterError(
            f"the kernel needs {(2 * nx + 1) * (2 * ny + 1)} OTF values (period {L} px), more "
            f"than {MAX_OTF_SAMPLES}: give a smaller size or a larger max_lost"
        )
    nu_x, nu_y = np.arange(-nx, nx + 1) / L, np.arange(-ny, ny + 1) / L
    wx, wy = _weights(nu_x, sampling), _weights(nu_y, sampling)
    acc = np.zeros((L, L), dtype=complex)
    block = max(1, min(L, MAX_OTF_SAMPLES // 16 // (2 * nx + 1)))  # rows per block
    for r0 in range(0, nu_y.size, block):
        rows = slice(r0, min(r0 + block, nu_y.size))
        vals = otf.grid(nu_x, nu_y[rows]) * wy[rows, None] * wx[None, :]
        folded = np.zeros((vals.shape[0], L), dtype=complex)
        for cols, idx in _fold_index(nx, L):
            folded[:, idx] += vals[:, cols]
        ky = np.arange(-ny, ny + 1)[rows] % L
        for i in range(0, ky.size, L):  # distinct row indices per chunk
            acc[ky[i : i + L]] += folded[i : i + L]
    k = np.fft.ifft2(acc).real  # Hermitian sum: the imaginary part is rounding only
    return np.fft.fftshift(k)


def box_masses(k: np.ndarray) -> np.ndarray:
    """sum |k| inside the centred boxes of half-width 0, 1, ..., L//2 - 1 (L even or odd)."""
    L = k.shape[0]
    c = L // 2
    P = np.zeros((L + 1, L + 1))
    P[1:, 1:] = np.abs(k).cumsum(0).cumsum(1)
    h = np.arange(min(c, L - c - 1) + 1)
    lo, hi = c - h, c + h + 1
    return P[hi, hi] - P[lo, hi] - P[hi, lo] + P[lo, lo]


def _refuse_size(need: int, otf: OTF, max_lost: float) -> None:
    raise ParameterError(
        f"a diffraction kernel that keeps all but max_lost = {max_lost:g} of this pupil's light "
        f"needs about {need} px (its tail beyond a box of half-width h is ~{otf.tail_px:.3g} "
        f"px / h), more than {MAX_KERNEL_PX} px: the opening diffracts too widely for a kernel; "
        "give a larger max_lost, or a size and a max_lost that accepts the loss"
    )


def kernel_side_px(tail_px: float, max_lost: float = DEFAULT_MAX_LOST) -> int:
    """The odd kernel side :func:`kernel_from_otf` first tries for an OTF whose tail is
    ``tail_px`` (:attr:`~.otf.OTF.tail_px`): the box whose tail beyond it is ``max_lost``."""
    return 2 * math.ceil(tail_px / max_lost) + 1


def kernel_period_px(side_px: int) -> int:
    """The period L of the Fourier sum for a kernel of side ``side_px``: four sides (so the
    aliased tail is a quarter of the kept one), a fast FFT length; its cost is ~L^2."""
    return min(fast_len(max(4 * side_px, 64)), MAX_PERIOD_PX)


def kernel_from_otf(
    otf: OTF,
    size: int | None = None,
    max_lost: float = DEFAULT_MAX_LOST,
    sampling: str = "pixel",
) -> DiffractionKernel:
    """The pixel-grid kernel of an OTF (module docstring), with its stated errors.

    Parameters
    ----------
    otf : OTF
        From :func:`~pacam_render.wave.otf.pupil_otf` (or any normalised, band-limited OTF).
    size : int, optional
        Odd kernel side, px; default the smallest that loses at most ``max_lost``.
    max_lost : float
        Refuse (ParameterError) a kernel that leaves out more than this fraction of the
        light, in (0, 0.5].
    sampling : {"pixel", "band"}
        ``"pixel"``: the PSF integrated over each pixel (the package's kernel convention);
        ``"band"``: the discrete filter with transfer function H on |nu| <= 1/2.

    Returns
    -------
    DiffractionKernel
    """
    if sampling not in SAMPLINGS:
        raise ParameterError(f"sampling must be one of {', '.join(SAMPLINGS)}, got {sampling!r}")
    max_lost = check_range("max_lost", max_lost, 1e-9, 0.5)
    if size is not None:
        if int(size) != size or size < 1 or size % 2 == 0 or size > MAX_KERNEL_PX:
            raise ParameterError(
                f"size must be an odd integer in [1, {MAX_KERNEL_PX}] px, got {size!r}"
            )
        want = int(size)
    else:
        want = kernel_side_px(otf.tail_px, max_lost)
        if want > MAX_KERNEL_PX:
            _refuse_size(want, otf, max_lost)
    while True:
        L = kernel_period_px(want)
        check_memory(f"a {L}x{L} Fourier sum", 40.0 * L * L, "size or max_lost")
        k = periodic_kernel(otf, L, sampling)
        if sampling == "pixel":
            k = np.maximum(k, 0.0)  # a pixel-integrated intensity: negatives are rounding
        total = float(k.sum())
        masses = box_masses(k)
        lost_h = (float(np.abs(k).sum()) - masses) / total
        if size is not None:
            h = want // 2
        else:
            ok = np.flatnonzero(lost_h <= max_lost)
            if ok.size == 0 or 2 * ok[0] + 1 > MAX_KERNEL_PX:
                _refuse_size(max(2 * lost_h.size + 1, want), otf, max_lost)
            h = int(ok[0])
            if 4 * (2 * h + 1) > L and L < MAX_PERIOD_PX:  # the tail was underestimated
                want = 2 * h + 1
                continue
        break
    lost = float(max(lost_h[h], 0.0))
    if lost > max_lost:
        raise ParameterError(
            f"{lost:.3%} of the diffracted light falls outside the {2 * h + 1} px kernel, more "
            f"than max_lost = {max_lost:g}; give a larger size or a larger max_lost"
        )
    c = L // 2
    kernel = k[c - h : c + h + 1, c - h : c + h + 1].copy()
    kernel /= kernel.sum()
    alias = lost * (h + 0.5) / max(L - h - 0.5, 1.0)
    return DiffractionKernel(kernel, lost, float(alias), L, sampling)


def fraunhofer_kernel(
    pupil,
    scale: DiffractionScale,
    size: int | None = None,
    max_lost: float = DEFAULT_MAX_LOST,
    sampling: str = "pixel",
) -> DiffractionKernel:
    """The incoherent Fraunhofer PSF |FT(pupil)|^2 on the sensor's pixels, normalised.

    Parameters
    ----------
    pupil : DiscPupil or GridPupil
        The opening (:mod:`.pupil`), in mm on the LCoS.
    scale : DiffractionScale
        Wavelength, pixel pitch and pupil distance D = 2 F_min R_max (:mod:`.scale`).
    size, max_lost, sampling
        As for :func:`kernel_from_otf`.

    Returns
    -------
    DiffractionKernel
        ``.kernel`` odd, centred, summing to 1; ``.lost`` and ``.alias`` its stated errors.

    Examples
    --------
    The prototype's F9.85 opening at 550 nm: 64 % of the light in the centre pixel, and a
    153 px kernel to keep all but 0.2 % of it.

    >>> from pacam_render.wave.pupil import DiscPupil
    >>> s = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * 0.01362)
    >>> d = fraunhofer_kernel(DiscPupil(145.5 * 0.01362), s)
    >>> d.kernel.shape, round(float(d.kernel[76, 76]), 3), d.lost <= 0.002
    ((153, 153), 0.644, True)
    """
    return kernel_from_otf(pupil_otf(pupil, scale), size, max_lost, sampling)
