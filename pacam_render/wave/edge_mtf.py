"""The MTF of an imaging chain measured from a slanted edge (after ISO 12233:2017, Sec. 6.4).

A straight edge at a small angle to the pixel columns is seen by each row at a different
sub-pixel phase, so projecting every pixel onto the edge's normal samples the edge spread
function (ESF) finer than the pixels. Its derivative, the line spread function (LSF), Fourier
transformed, is the MTF along the normal. Two departures from the standard, for images
without noise whose edge is known:

- the edge's position is given (a synthetic or rendered edge of known geometry), so no edge
  fit adds error;
- with tan(angle) = 1/m the rows sample m distinct phases, and the ESF is binned at 1/m px:
  one phase per bin, so the bins sample the ESF exactly where it was seen. The standard's
  4x bins average several phases and fold the pixel's sinc back into the band: on an edge
  at tan = 1/16 they move an MTF ratio by up to 0.02 (measured; see ``tests/wave``);
- no Hamming window, and no normalisation by the windowed LSF's sum (diffraction's long
  tail leaves the window, which would bias every ratio by the tail's share): the spectrum is
  divided by the edge's contrast, which a ratio of two MTFs of one edge does not need.

Used for issue 36's check: the ratio of an in-focus edge's MTF with diffraction to its MTF
without is the circular pupil's MTF (:func:`~pacam_render.wave.reference.circular_mtf`).
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError


def edge_mtf(
    image,
    angle_deg: float,
    offset_px: float,
    nu_cycles_per_px,
    half_width_px: float = 30.0,
    oversample: int | None = None,
    contrast: float = 1.0,
) -> np.ndarray:
    """|FT(LSF)| along a straight edge's normal at ``nu_cycles_per_px``, over ``contrast``.

    Parameters
    ----------
    image : array_like
        ``(H, W)``, linear values, one side of the edge darker than the other.
    angle_deg : float
        The edge's tilt from the columns, degrees, |angle| in (0.6, 26): it runs through
        pixel-centre coordinates x = offset_px + y tan(angle) (x along columns, y along rows,
        both from the centre of pixel (0, 0)).
    offset_px : float
        Where the edge crosses row 0, px.
    nu_cycles_per_px : array_like
        Frequencies along the normal, cycles/px.
    half_width_px : float
        The ESF is kept within this distance of the edge, px.
    oversample : int, optional
        ESF bins per px; default round(1 / |tan(angle)|) (module docstring).
    contrast : float
        The edge's step (bright minus dark); 1 for a unit step.

    Returns
    -------
    numpy.ndarray
        The MTF at each frequency (1 at 0 for an edge whose light stays in the window).

    Examples
    --------
    A pixel-integrated edge (no optics) has the pixel's MTF, |sinc(nu)|, along its normal:

    >>> y, x = np.mgrid[0:64, 0:64] + 0.0
    >>> t = 1 / 16
    >>> img = np.clip(x + 0.5 - 20 - y * t, 0, 1)  # the step's area in each pixel, ~exact
    >>> m = edge_mtf(img, np.degrees(np.arctan(t)), 20.0, [0.25], half_width_px=12)
    >>> round(float(m[0]), 2), round(float(np.sinc(0.25)), 2)
    (0.9, 0.9)
    """
    img = np.asarray(image, dtype=float)
    if img.ndim != 2:
        raise ParameterError(f"image must be (H, W), got shape {img.shape}")
    t = float(np.tan(np.radians(float(angle_deg))))
    if not 0.01 < abs(t) < 0.5:
        raise ParameterError(f"angle_deg must be in (0.6, 26) deg in size, got {angle_deg!r}")
    m = int(oversample) if oversample is not None else max(1, round(1.0 / abs(t)))
    h, w = img.shape
    y, x = np.mgrid[0:h, 0:w].astype(float)
    d = (x - offset_px - y * t) / np.sqrt(1.0 + t * t)  # signed distance to the edge, px
    keep = np.abs(d) <= half_width_px
    bins = np.round(d[keep] * m).astype(int)
    lo = bins.min()
    count = np.bincount(bins - lo)
    if np.any(count == 0):
        raise ParameterError(
            f"oversample = {m}: some ESF bins are empty; the edge needs at least {m} rows"
        )
    esf = np.bincount(bins - lo, weights=img[keep]) / count
    lsf = np.gradient(esf)
    pos = (np.arange(esf.size) + lo) / m  # px
    nu = np.asarray(nu_cycles_per_px, dtype=float)
    return np.abs(np.exp(-2j * np.pi * np.outer(nu, pos)) @ lsf) / float(contrast)


def fit_edge(image) -> tuple[float, float]:
    """(angle deg, offset px) of a straight edge: its 50 % crossing in each row that crosses
    once, linearly interpolated, and a line fitted over the rows (the ``angle_deg`` and
    ``offset_px`` of :func:`edge_mtf`).

    Examples
    --------
    >>> y, x = np.mgrid[0:64, 0:64] + 0.0
    >>> img = np.clip(x + 0.5 - 20 - y / 16, 0, 1)
    >>> [round(v, 1) for v in fit_edge(img)]  # atan(1/16) = 3.58 deg
    [3.5, 20.0]
    """
    img = np.asarray(image, dtype=float)
    half = 0.5 * (img.max() + img.min())
    ys, xs = [], []
    for y, row in enumerate(img):
        bright = row > half
        j = np.flatnonzero(bright[1:] != bright[:-1])
        if j.size != 1:
            continue
        j = int(j[0])
        xs.append(j + (half - row[j]) / (row[j + 1] - row[j]))
        ys.append(y)
    if len(ys) < 2:
        raise ParameterError("image: fewer than two rows cross the edge once")
    slope, offset = np.polyfit(ys, xs, 1)
    return float(np.degrees(np.arctan(slope))), float(offset)
