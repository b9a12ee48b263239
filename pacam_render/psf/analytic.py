"""Analytic PSFs on the pixel grid (paper Eqs. 1, 13, 14, and the baselines).

Every kernel is a normalised float64 (h, w) array, odd-sized and centred: pixel
(h//2, w//2) spans [-1/2, 1/2)^2 around the origin, and each value is the PSF *integrated over the
pixel*, never sampled at its centre. Motion is along +x (columns). The origin is where the point
images at mid-exposure, t = 0, so that x(t) = s t + a_i t^2 / 2 (Eq. 2).

How it is computed:
- the motion part comes from :mod:`pacam_render.psf.trajectory`: the exact time spent in each pixel
  (closed form, so Eq. 1's vertex singularity is integrated, never sampled);
- with defocus (r > 0), the trajectory is cut into sub-pixel bins of width ``du_px`` whose exact
  time and centroid are known, and each bin deposits an exactly integrated pillbox
  (:mod:`pacam_render.psf.pillbox`) at its centroid. This is exact for the discrete schedule at
  s = 0 (every pattern is an atom) and second order in ``du_px`` otherwise;
  ``benchmarks/bench_psf.py`` measures its error against run time.

Units: s in px/ms, a_i in px/ms^2, T (half the exposure, the paper's 2T convention) and
exposure in ms, r in px.
"""

from __future__ import annotations

import math

import numpy as np
from tqdm import tqdm

from ..errors import ParameterError, check_finite, check_positive
from ..model import paper
from ..model import schedule as sch
from ..model.modes import (
    DESIGNED_REFUSED,
    MODES,
    MODES_WITH_PSF,
    capture_camera,
    held_offsets_px,
    mode_exposure_ms,
    t0_offset_px,
)
from .bitmap import bitmap_kernel, bitmap_lost_fraction
from .diffraction import DEFAULT_MAX_LOST, diffracted_kernel
from .grid import (  # the limit and the warning are also read here by earlier callers
    MAX_LOST_FRACTION,  # noqa: F401
    R_DELTA_PX,
    PSFTruncationWarning,  # noqa: F401
    auto_size,
    kernel_shape,
    normalise,
)
from .pillbox import disc_coverage, quadrant_area
from .planar import planar_kernel
from .trajectory import Segment, bin_statistics, extent, total_weight


def default_du_px(r_px: float) -> float:
    """Default quadrature bin for the defocused motion PSF, px (see bench_psf.py)."""
    return min(0.05, r_px / 4.0)


def _deposit_discs(kernel, xe, ye, r, centres, masses) -> None:
    """Add masses * pillbox(centre) coverage to kernel, touching only the pixels each disc meets."""
    h, w = kernel.shape
    nw = math.ceil(2 * r) + 2
    rows = [i for i in range(h) if ye[i] < r and ye[i + 1] > -r]
    chunk = max(1, 2_000_000 // (nw * max(1, len(rows))))
    starts = range(0, centres.size, chunk)
    # a bar on a terminal once a kernel takes over 2 s (a few reach 10 s: r ~ 25 px, 2049 px)
    for k0 in tqdm(starts, desc="PSF", unit="chunk", delay=2.0, disable=None, leave=False):
        cx, m = centres[k0 : k0 + chunk], masses[k0 : k0 + chunk]
        j0 = np.floor(cx - r - xe[0]).astype(np.int64)  # first column a disc can touch
        cols = j0[:, None] + np.arange(nw + 1)[None, :]
        dx = (xe[0] + cols) - cx[:, None]  # local column edges relative to each centre
        for i in rows:
            cum = quadrant_area(dx, np.full_like(dx, ye[i + 1]), r) - quadrant_area(
                dx, np.full_like(dx, ye[i]), r
            )
            cov = np.maximum(np.diff(cum, axis=1), 0.0) * m[:, None]
            jj = cols[:, :-1]
            ok = (jj >= 0) & (jj < w)
            kernel[i] += np.bincount(jj[ok], weights=cov[ok], minlength=w)


def kernel_from_trajectory(
    segments: list[Segment], r_px: float = 0.0, size=None, du_px: float | None = None
) -> np.ndarray:
    """Pixel-integrated PSF of a point moving along ``segments``, blurred by a pillbox r_px.

    Segments on other rows than 0 (a designed schedule's vertical offsets, ``Segment.y``) are
    deposited row by row; the rows' masses add.
    """
    r = float(r_px)
    if not math.isfinite(r) or r < 0:
        raise ParameterError(f"r_px must be a finite radius >= 0 px, got {r_px!r}")
    if r < R_DELTA_PX:
        r = 0.0
    lo, hi = extent(segments)
    ys = sorted({seg.y for seg in segments})
    y_max = max(abs(ys[0]), abs(ys[-1]))
    h, w = kernel_shape(size, lo - y_max, hi + y_max, r)
    xe = np.arange(w + 1) - w // 2 - 0.5
    ye = np.arange(h + 1) - h // 2 - 0.5
    kernel = np.zeros((h, w))
    for y in ys:
        row = [seg for seg in segments if seg.y == y]
        _deposit_row(kernel, row, xe, ye - y, r, du_px, extent(row))
    return normalise(kernel, total_weight(segments))


def _deposit_row(kernel, segments, xe, ye, r: float, du_px, span) -> None:
    """Add the segments' pixel-integrated mass, on the row ye's origin stands for."""
    h = kernel.shape[0]
    lo, hi = span
    if r == 0.0:
        i = int(np.searchsorted(ye, 0.0, side="right")) - 1  # the row whose pixel holds y
        if 0 <= i < h:
            kernel[i] += bin_statistics(segments, xe)[0]
        return
    du = default_du_px(r) if du_px is None else check_positive("du_px", du_px, "px")
    ulo, uhi = max(lo, xe[0] - r), min(hi, xe[-1] + r)
    if ulo <= uhi:
        n = max(1, math.ceil((uhi - ulo) / du))
        ue = np.linspace(ulo - 0.5 * du, uhi + 0.5 * du, n + 2)
        mass, moment = bin_statistics(segments, ue)
        keep = mass > 0.0
        centres = moment[keep] / mass[keep]
        _deposit_discs(kernel, xe, ye, r, centres, mass[keep] / (math.pi * r * r))


def _check_motion(s: float, a_i: float, T_ms: float) -> tuple[float, float, float]:
    return (
        check_finite("s (px/ms)", s),
        check_finite("a_i (px/ms^2)", a_i),
        check_positive("T_ms", T_ms, "ms"),
    )


def parabola_segments(s: float, a_i: float, T_ms: float, x0_px: float = 0.0) -> list[Segment]:
    """Eq. 2 over the whole exposure: x(t) = x0 + s t + a_i t^2 / 2, t in [-T, T]."""
    s, a, T = _check_motion(s, a_i, T_ms)
    return [Segment(-T, T, check_finite("x0_px", x0_px), s, a)]


def discrete_segments(
    s: float, a_i: float, T_ms: float, n_patterns: int = paper.N_PATTERNS, x0_px: float = 0.0
) -> list[Segment]:
    """What the LCoS really shows: n held positions x0 + a_i t_k^2 / 2, while the object moves."""
    s, a, T = _check_motion(s, a_i, T_ms)
    x0 = check_finite("x0_px", x0_px)
    edges = sch.pattern_edges_ms(T, n_patterns)
    mids = sch.pattern_mid_times_ms(T, n_patterns)
    return [
        Segment(e0, e1, x0 + 0.5 * a * tk * tk, s, 0.0)
        for e0, e1, tk in zip(edges[:-1], edges[1:], mids)
    ]


def levin_psf(s: float, a_i: float, T_ms: float, size=None, x0_px: float = 0.0) -> np.ndarray:
    """phi (Eq. 1): parabolic motion, in focus. Also Levin et al.'s camera-motion baseline."""
    return kernel_from_trajectory(parabola_segments(s, a_i, T_ms, x0_px), 0.0, size)


def pillbox_psf(r_px: float, size=None, centre=(0.0, 0.0)) -> np.ndarray:
    """psi (Eq. 13): a uniform disc of radius r_px with exact pixel coverage.

    Examples
    --------
    >>> k = pillbox_psf(2.0)
    >>> k.shape, round(float(k.sum()), 12), round(float(k[3, 3]), 4)
    ((7, 7), 1.0, 0.0796)
    """
    r = float(r_px)
    if not math.isfinite(r) or r < 0:
        raise ParameterError(f"r_px must be a finite radius >= 0 px, got {r_px!r}")
    cx = check_finite("centre x (px)", centre[0])
    cy = check_finite("centre y (px)", centre[1])

    n = auto_size(-abs(cx) - abs(cy), abs(cx) + abs(cy), r)
    shape = kernel_shape(size if size is not None else n, 0, 0, r)
    cov = disc_coverage(r if r >= R_DELTA_PX else 0.0, shape, (cx, cy))
    return normalise(cov, 1.0 if r < R_DELTA_PX else math.pi * r * r)


def coded_psf(
    s: float,
    a_i: float,
    r_px: float,
    T_ms: float,
    size=None,
    du_px: float | None = None,
    x0_px: float = 0.0,
) -> np.ndarray:
    """Phi = phi * psi (Eq. 14): the paper's continuous model of the coded capture."""
    return kernel_from_trajectory(parabola_segments(s, a_i, T_ms, x0_px), r_px, size, du_px)


def discrete_coded_psf(
    s: float,
    a_i: float,
    r_px: float,
    T_ms: float,
    n_patterns: int = paper.N_PATTERNS,
    size=None,
    du_px: float | None = None,
    x0_px: float = 0.0,
) -> np.ndarray:
    """The coded capture's exact PSF: n pillboxes, each held 2T/n and smeared by the motion."""
    segs = discrete_segments(s, a_i, T_ms, n_patterns, x0_px)
    return kernel_from_trajectory(segs, r_px, size, du_px)


def static_psf(s: float, T_ms: float, r_px: float = 0.0, size=None) -> np.ndarray:
    """A normal camera: a box of length |s| 2T, blurred by defocus r_px if any."""
    return kernel_from_trajectory(parabola_segments(s, 0.0, T_ms), r_px, size)


def short_exposure_psf(s: float, exposure_ms: float, r_px: float = 0.0, size=None) -> np.ndarray:
    """A short exposure (the paper's 0.679 ms at F2.8): a box of length |s| exposure."""
    T = 0.5 * check_positive("exposure_ms", exposure_ms, "ms")
    return static_psf(s, T, r_px, size)


def flutter_psf(
    s: float, T_ms: float, code: str = sch.RASKAR_2006_CODE, r_px: float = 0.0, size=None
) -> np.ndarray:
    """Raskar et al. 2006: the shutter opens and closes per chop of ``code`` over [-T, T]."""
    return kernel_from_trajectory(flutter_segments(s, T_ms, code), r_px, size)


def invariance_tail_l1(s: float, a_i: float, T_ms: float) -> float:
    """L1 distance between the s-PSF (shifted back by s^2 / 2a_i) and the s = 0 PSF.

    Completing the square in Eq. 2, x(t) = a_i (t + s/a_i)^2 / 2 - s^2 / (2 a_i): inside the
    range |s| <= |a_i| T the motion is the s = 0 parabola seen through a time window shifted by
    s/a_i, so a fraction |s| / (2 |a_i| T) of the exposure leaves one wing and the same enters
    the other. The two tails do not overlap, so the L1 distance is |s| / (|a_i| T), at most 1.
    """
    s, a, T = _check_motion(s, a_i, T_ms)
    if a == 0.0 or abs(s) > abs(a) * T:
        raise ParameterError(
            f"s = {s:g} px/ms is outside the invariant range |s| <= |a_i| T = {abs(a) * T:g}"
        )
    return abs(s) / (abs(a) * T)


def vertex_shift_px(s: float, a_i: float) -> float:
    """Shift of the motion-invariant PSF at speed s: -s^2 / (2 a_i), px."""
    return -s * s / (2.0 * a_i)


def flutter_segments(s: float, T_ms: float, code: str = sch.RASKAR_2006_CODE) -> list[Segment]:
    """Raskar et al.'s shutter: the point moves at s, seen only during the open chops."""
    s, _, T = _check_motion(s, 0.0, T_ms)
    bits = sch.flutter_code(code)
    edges = np.linspace(-T, T, bits.size + 1)
    return [Segment(e0, e1, 0.0, s, 0.0, b) for e0, e1, b in zip(edges[:-1], edges[1:], bits)]


def designed_segments(cam, s: float, x0_px: float = 0.0) -> list[Segment]:
    """A designed schedule (``cam.pattern_centres_mm``): pattern k holds the point's image at
    x0 + beta_px X_k - (the t = 0 pattern's), on row beta_px Y_k (Eq. 8), while it moves at s.

    Parameters
    ----------
    cam : CameraDesign
        With ``pattern_centres_mm`` set.
    s : float
        Image speed, px/ms.
    x0_px : float
        Where the pattern shown at t = 0 images the point, px.
    """

    s = check_finite("s (px/ms)", s)
    off = held_offsets_px(cam)
    off[:, 0] += check_finite("x0_px", x0_px)
    edges = sch.pattern_edges_ms(cam.T_ms, cam.n_patterns)
    return [Segment(e0, e1, u, s, 0.0, y=v) for e0, e1, (u, v) in zip(edges[:-1], edges[1:], off)]


def _coded_segments(cam, s: float, x0: float) -> list[Segment]:
    if cam.designed:
        return designed_segments(cam, s, x0)
    return discrete_segments(s, cam.a_i_px_per_ms2, cam.T_ms, cam.n_patterns, x0)


MODE_TRAJECTORIES = {
    "discrete_coded": lambda cam, s, x0: (_coded_segments(cam, s, x0), cam.r_px),
    "coded": lambda cam, s, x0: (parabola_segments(s, cam.a_i_px_per_ms2, cam.T_ms, x0), cam.r_px),
    "levin": lambda cam, s, x0: (parabola_segments(s, cam.a_i_px_per_ms2, cam.T_ms, x0), 0.0),
    "static": lambda cam, s, x0: (parabola_segments(s, 0.0, cam.T_ms), cam.r_px),
    "short": lambda cam, s, x0: (
        parabola_segments(s, 0.0, 0.5 * mode_exposure_ms(cam, "short")),
        cam.r_px,
    ),
    "flutter": lambda cam, s, x0: (flutter_segments(s, cam.T_ms), cam.r_px),
}
"""The trajectory of each analytic kernel that :data:`pacam_render.model.modes.MODES` names,
by its ``psf`` key: ``f(camera, s_px_per_ms, x0_px) -> (segments, r_px)``, the image of a
point's x over the exposure and the defocus disc that it carries."""


def _shows_bitmaps(design, mode: str) -> bool:
    """A bitmap schedule in a mode that shows its patterns: its kernel is the patterns
    themselves, projected through the lens (:mod:`.bitmap`), not discs along a trajectory."""
    if design.pattern_masks is None or mode not in MODES_WITH_PSF:
        return False
    if mode in DESIGNED_REFUSED:
        capture_camera(design, mode)  # raises, naming what the designed schedule lacks
    if MODES[mode].psf != "discrete_coded":
        return False
    design.require_parallax()
    return True


def _bitmap_call(fn, design, s: float, origin: str, **kw):
    """``fn`` (:func:`.bitmap.bitmap_kernel` or ``bitmap_lost_fraction``) for the design's
    stack, pitch, beta (Eq. 8) and T."""
    m = design.pattern_masks
    return fn(m.array, m.pitch_mm, design.beta_px_per_mm, design.T_ms, s, origin=origin, **kw)


def design_trajectory(design, mode: str = "coded", s: float = 0.0, origin: str = "t0"):
    """The trajectory of a point's image in a ``mode`` capture (see :func:`design_psf`).

    Returns
    -------
    segments : list of Segment
        x(t) over the exposure, px (Eq. 2, or the mode's own motion).
    r_px : float
        The defocus radius r = |beta| R (Eq. 12) of the disc the point images to, px.
    """
    if origin not in ("t0", "pinhole"):
        raise ParameterError(f"origin must be 't0' or 'pinhole', got {origin!r}")
    if mode not in MODES_WITH_PSF:
        raise ParameterError(f"unknown mode {mode!r}; valid: {', '.join(MODES_WITH_PSF)}")
    m = MODES[mode]
    if _shows_bitmaps(design, mode):
        raise ParameterError(
            "a bitmap schedule (pattern_masks) is not discs along a trajectory: its kernel is "
            "design_psf's (psf.bitmap.bitmap_kernel)"
        )
    if design.designed and mode in DESIGNED_REFUSED:
        capture_camera(design, mode)  # raises, naming what the designed schedule lacks
    if m.needs_parallax:
        design.require_parallax()
    x0 = t0_offset_px(design, mode) if origin == "pinhole" else 0.0
    return MODE_TRAJECTORIES[m.psf](design, s, x0)


def least_lost_fraction(
    design, mode: str = "coded", s: float = 0.0, size=None, origin: str = "t0"
) -> tuple[float, tuple[int, int], float]:
    """A lower bound on the mass that :func:`design_psf` would lose outside its kernel, without
    computing the kernel (whose cost grows with the defocus radius: minutes at r ~ 1e5 px).

    Every point of the path spreads over a disc of radius r, and an h x w window holds at most
    min(1, 2h / (pi r), 2w / (pi r), h w / (pi r^2)) of one disc.

    Parameters
    ----------
    design, mode, s, size, origin
        As for :func:`design_psf`.

    Returns
    -------
    lost : float
        The bound, a fraction of the PSF's mass in [0, 1).
    shape : (int, int)
        The kernel's (h, w): ``size``, or the automatic size (at most :data:`MAX_AUTO_SIZE`).
    r_px : float
        The defocus radius, px.
    """
    if _shows_bitmaps(design, mode):
        lost, shape = _bitmap_call(bitmap_lost_fraction, design, s, origin, size=size)
        return lost, shape, design.r_px
    segments, r = design_trajectory(design, mode, s, origin)
    lo, hi = extent(segments)
    y_max = max(abs(seg.y) for seg in segments)
    h, w = kernel_shape(size, lo - y_max, hi + y_max, r)
    if r < R_DELTA_PX:
        return 0.0, (h, w), r
    inside = min(1.0, 2 * h / (math.pi * r), 2 * w / (math.pi * r), h * w / (math.pi * r * r))
    return 1.0 - inside, (h, w), r


def design_psf(
    design,
    mode: str = "coded",
    s: float = 0.0,
    size=None,
    origin: str = "t0",
    v_px_per_ms=0.0,
    diffraction_nm: float | None = None,
):
    """The analytic PSF of a capture in ``mode`` by camera ``design``, at speed s.

    Parameters
    ----------
    design : CameraDesign
        The camera that takes the capture (for a capture of a coded design, pass
        :func:`~pacam_render.model.modes.capture_camera`'s result). A bitmap schedule
        (``pattern_masks``) in ``coded`` mode gets the exact kernel of its patterns projected
        through the lens (Eq. 8, :func:`~pacam_render.psf.bitmap.bitmap_kernel`).
    mode : str
        A mode of :data:`~pacam_render.model.modes.MODES` with an analytic PSF: ``coded``
        (the discrete n-pattern schedule the camera really shows), ``coded_continuous``
        (Eq. 14), ``levin`` (Eq. 1, the camera body moves, in focus), ``normal``, ``short``
        and ``flutter`` (a still aperture with the design's defocus r, Eq. 12).
    s : float
        Object speed in the image, px/ms.
    size : int or (int, int), optional
        Odd kernel size; default: just large enough.
    origin : {"t0", "pinhole"}
        What the kernel's centre pixel stands for. ``"t0"``: where the point images at
        mid-exposure (x(0) = 0 in Eq. 2). ``"pinhole"``: where a pinhole at the lens centre
        images it at mid-exposure, as the ``reference`` capture does; the moving aperture (and
        Levin's moving body) start from an edge, which shifts the image by -a_i T^2 / 4
        (:func:`~pacam_render.model.modes.t0_offset_px`). Deconvolve with ``"pinhole"`` to
        register with the scene.
    v_px_per_ms : float, optional
        Vertical image speed, px/ms (rows, downwards). 0 gives the exact kernel of the
        one-dimensional motion; otherwise the point's path is two-dimensional, and the kernel
        is its quadrature (:func:`~pacam_render.psf.planar.planar_kernel`).
    diffraction_nm : float, optional
        None (the default): the geometric kernel. A wavelength in nm: the kernel convolved
        with the diffraction of the mode's openings at that wavelength, the pixel's box counted
        once (:func:`~pacam_render.psf.diffraction.diffracted_kernel`; per colour channel
        :data:`~pacam_render.wave.patterns.CHANNEL_WAVELENGTHS_NM`). Without ``size`` the
        kernel grows by the diffraction kernel's size less one.

    Returns
    -------
    numpy.ndarray
        The pixel-integrated kernel, odd-sized, summing to 1.

    Examples
    --------
    The prototype's coded kernel at rest and inside its invariant range (|s| <= 0.9 px/ms)
    have the same support, shifted by -s^2 / (2 a_i):

    >>> from pacam_render.model.camera import preset
    >>> k0 = design_psf(preset("prototype"), "coded", s=0.0)
    >>> k0.shape, round(float(k0.sum()), 12)
    ((25, 25), 1.0)
    """
    if diffraction_nm is not None:  # the pixel's box counted once, as the rays count it
        shape = np.shape(design_psf(design, mode, s, size, origin, v_px_per_ms))

        def build(cam, f, fine):
            return design_psf(cam, mode, s * f, fine, origin, v_px_per_ms * f)

        lost = DEFAULT_MAX_LOST if size is None else None
        return diffracted_kernel(build, design, mode, diffraction_nm, shape, None, lost)
    if _shows_bitmaps(design, mode):
        return _bitmap_call(bitmap_kernel, design, s, origin, size=size, v_px_per_ms=v_px_per_ms)
    segments, r = design_trajectory(design, mode, s, origin)
    if v_px_per_ms == 0.0:
        return kernel_from_trajectory(segments, r, size)

    return planar_kernel(segments, r, v_px_per_ms, size)
