"""Reference captures with diffraction before the pixel: a scene on a grid q times finer than
the pixels, imaged exactly through an OTF in the Fourier domain.

The scene is periodic and constant on each fine cell (value s_j). Through optics of transfer
function H the irradiance is S * h, and a fine cell collects its integral over the cell, so
on the fine grid

    cell values = IDFT[ DFT(s) x H(nu) x sinc^2(nu_x / q) sinc^2(nu_y / q) ]

exactly, when H vanishes beyond q/2 cycles/px (the fine grid's Nyquist: the two boxes are the
scene's cells and the cells' integration; their aliases sum to one, so without optics the
cells give back s). Summing the q x q cells of a pixel gives the pixel-integrated capture.
The post-process of :mod:`.image` is measured against this in
``benchmarks/bench_diffraction.py`` and ``tests/wave/test_image.py``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError


def supersampled_capture(fine, q: int, transfer=None, nyquist_tol: float = 1e-12) -> np.ndarray:
    """The pixel values of a periodic fine-grid scene imaged through ``transfer``.

    Parameters
    ----------
    fine : array_like
        ``(N q, M q)`` fine cells' radiance, periodic.
    q : int
        Fine cells per pixel along each axis.
    transfer : callable, optional
        ``transfer(nu_x, nu_y) -> (len(nu_y), len(nu_x))``, the optics' OTF on frequencies in
        cycles/px (e.g. :attr:`~pacam_render.wave.otf.OTF.grid`); it must vanish beyond
        q / 2 cycles/px. None: no optics (the geometric capture).
    nyquist_tol : float
        Largest |transfer x sinc^2| accepted at the fine grid's Nyquist. A transfer that is
        not band-limited (a geometric pillbox, 2 J1(2 pi r nu) / (2 pi r nu)) leaves out its
        aliases beyond q / 2, an error of that order at the finest scales.

    Returns
    -------
    numpy.ndarray
        ``(N, M)`` pixel means.
    """
    s = np.asarray(fine, dtype=float)
    q = int(q)
    if s.ndim != 2 or q < 1 or s.shape[0] % q or s.shape[1] % q:
        raise ParameterError(f"fine must be (N q, M q) for q = {q!r}, got shape {s.shape}")
    if transfer is not None:
        ny = np.fft.fftfreq(s.shape[0], d=1.0 / q)  # cycles/px
        nx = np.fft.rfftfreq(s.shape[1], d=1.0 / q)
        t = np.asarray(transfer(nx, ny)) * np.sinc(ny / q)[:, None] ** 2 * np.sinc(nx / q) ** 2
        edge = max(np.abs(t[:, -1]).max(), np.abs(t[s.shape[0] // 2]).max())
        if edge > nyquist_tol:
            raise ParameterError(
                f"transfer must vanish at the fine grid's Nyquist (q / 2): it is {edge:.3g} "
                f"there, above nyquist_tol = {nyquist_tol:g}; use a larger q"
            )
        s = np.fft.irfft2(np.fft.rfft2(s) * t, s.shape)
    n, m = s.shape[0] // q, s.shape[1] // q
    return s.reshape(n, q, m, q).mean(axis=(1, 3))
