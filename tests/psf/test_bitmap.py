"""The bitmap-stack PSF (issue 35) against independent references: the designed schedule's disc
kernels, the pillbox and box closed forms, brute-force sampling, and the stiff cases.

The disc stacks are rasterised, so they match the ideal discs only up to a rasterisation error;
:func:`raster_bound` computes a rigorous L1 bound on it from the exact pixel coverage of each disc
(:func:`pacam_render.psf.pillbox.disc_coverage`), independently of the code under test.
"""

import math
import time
import warnings

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.camera import prototype
from pacam_render.model.masks import disc_mask, disc_masks
from pacam_render.model.modes import local_centres_mm, pattern_offsets_px
from pacam_render.psf.analytic import (
    designed_segments,
    kernel_from_trajectory,
    pillbox_psf,
    static_psf,
)
from pacam_render.psf.bitmap import (
    bitmap_extent_px,
    bitmap_kernel,
    bitmap_lost_fraction,
    bitmap_offsets_px,
)
from pacam_render.psf.grid import PSFTruncationWarning
from pacam_render.psf.pillbox import disc_coverage
from pacam_render.psf.planar import planar_kernel

SHAPE = (384, 1100)  # even sides; holds the discs below (|x| + R <= 510, |y| + R <= 183 px)
SUPERSAMPLE = 8
CAM0 = prototype()
PITCH, BETA, T = CAM0.lcos_pitch_mm, CAM0.beta_px_per_mm, CAM0.T_ms


def designed(centres_mm=None, **changes):
    """The prototype with a designed schedule (design frame: x right, y down, mm)."""
    c = CAM0.pattern_centres_xy_mm() if centres_mm is None else np.asarray(centres_mm, float)
    return CAM0.with_(pattern_centres_mm=tuple(map(tuple, c)), n_patterns=len(c), **changes)


def discs_of(cam, shape=SHAPE, supersample=SUPERSAMPLE):
    """The disc stack the camera shows; disc_masks takes the plugin's local frame (-x, -y)."""
    return disc_masks(local_centres_mm(cam), cam.R_mm, shape, cam.lcos_pitch_mm, supersample)


def pinhole_segments(cam, s):
    """designed_segments with u from the pinhole image (x0 undoes the t = 0 pattern's shift)."""
    return designed_segments(cam, s, x0_px=pattern_offsets_px(cam)[cam.n_patterns // 2, 0])


def coverages(cam, shape):
    """Exact area of each ideal disc in each LCoS pixel, in pixels (independent of the code)."""
    r_lcos = cam.R_mm / cam.lcos_pitch_mm
    # disc_coverage's pixel j is centred at j - w // 2, the LCoS pixel's X (px) minus 1/2
    centres = cam.pattern_centres_xy_mm() / cam.lcos_pitch_mm - 0.5
    return [disc_coverage(r_lcos, shape, tuple(c)) for c in centres]


def raster_bound(masks, cam, s, weights=None, covs=None):
    """Rigorous L1 bound between the bitmap kernel of ``masks`` and the ideal discs' kernel.

    LCoS pixel q of pattern k holds light tau/M (bitmap) against c/M' (the disc's exact coverage
    c, spread over the part S of the pixel inside the disc). Their difference is a mass term,
    |tau/M - c/M'|, plus c/M' times (uniform on the pixel's image square Q - uniform on S's).
    That term's L1 is 2 (1 - c) before pixel integration, which keeps it only where Q straddles
    a kernel pixel edge; a sweep of length L along u turns it into <= 2 W1 / L <= 2 b / L in
    the row (Q of side b). ``weights``: each window's shutter weight in the ideal kernel.
    """
    n, h, w = masks.shape
    weights = np.ones(n) if weights is None else np.asarray(weights, float)
    b = abs(cam.beta_px_per_mm) * cam.lcos_pitch_mm
    u = cam.beta_px_per_mm * cam.lcos_pitch_mm * (np.arange(w) + 0.5 - w / 2)
    v = cam.beta_px_per_mm * cam.lcos_pitch_mm * (np.arange(h) + 0.5 - h / 2)

    def straddles(c):
        return np.floor(c - b / 2 + 0.5) != np.floor(c + b / 2 + 0.5)

    sweep = abs(s) * cam.exposure_ms / n
    g_u = np.full(w, min(2.0, 2 * b / sweep)) if sweep > 0 else 2.0 * straddles(u)
    g = np.where(straddles(v)[:, None], 2.0, g_u[None, :])
    total = float((masks.sum(axis=(1, 2)) * (weights > 0)).sum())
    bound = 0.0
    for k, cov in enumerate(coverages(cam, (h, w)) if covs is None else covs):
        ideal = weights[k] * cov / (cov.sum() * weights.sum())
        bound += np.abs(masks[k] * (weights[k] > 0) / total - ideal).sum()
        bound += (ideal * np.minimum(g, 2.0 * (1.0 - cov))).sum()
    return bound


def l1(a, b):
    assert a.shape == b.shape
    return float(np.abs(a - b).sum())


def assert_valid(k):
    assert np.all(np.isfinite(k)) and k.min() >= 0.0
    assert k.sum() == pytest.approx(1.0, abs=1e-12)
    assert k.shape[0] % 2 == 1 and k.shape[1] % 2 == 1


ASYMMETRIC = np.stack([np.linspace(-4.5, 4.5, 16) ** 3 / 20.25, 0.5 * np.sin(np.arange(16))], 1)
"""A designed schedule with no symmetry in time and a vertical component, mm."""


@pytest.fixture(scope="module", params=["parabola", "asymmetric"])
def proto(request):
    cam = designed(None if request.param == "parabola" else ASYMMETRIC)
    return cam, discs_of(cam), coverages(cam, SHAPE)


# --- the designed schedule's discs ---------------------------------------------------------------


@pytest.mark.parametrize("s", [0.0, 0.5])
def test_disc_stack_reproduces_designed_kernel(proto, s):
    cam, masks, covs = proto
    ref = kernel_from_trajectory(pinhole_segments(cam, s), cam.r_px, du_px=0.004)
    k = bitmap_kernel(masks, PITCH, BETA, T, s, size=ref.shape, origin="pinhole")
    assert_valid(k)
    bound = raster_bound(masks, cam, s, covs=covs)
    # the reference's own quadrature error (du = 0.004 px, second order) is < 1e-6 at s = 0.5
    assert l1(k, ref) <= bound + 1e-6
    assert bound < 1e-3  # tight enough to catch half an LCoS pixel of offset (L1 2.5e-3)
    # and the residual is the rasterisation: a binary stack is farther from the ideal discs
    binary = bitmap_kernel(discs_of(cam, supersample=1), PITCH, BETA, T, s, size=ref.shape,
                           origin="pinhole")  # fmt: skip
    assert l1(binary, ref) > 3 * l1(k, ref)


def test_t0_origin_is_the_t0_pattern_centroid(proto):
    cam, masks, covs = proto
    off = bitmap_offsets_px(masks, PITCH, BETA)
    # each pattern images where the design says (Eq. 8), to the raster's centroid error
    np.testing.assert_allclose(off, pattern_offsets_px(cam), atol=2e-4)
    k0 = bitmap_kernel(masks, PITCH, BETA, T, 0.5, size=45)
    kp = bitmap_kernel(masks, PITCH, BETA, T, 0.5, size=45, origin="pinhole",
                       x0_px=-off[cam.n_patterns // 2, 0])  # fmt: skip
    np.testing.assert_allclose(k0, kp, atol=1e-13)
    ref = kernel_from_trajectory(designed_segments(cam, 0.5), cam.r_px, size=45, du_px=0.004)
    assert l1(k0, ref) <= raster_bound(masks, cam, 0.5, covs=covs) + 1e-6


def test_black_patterns_shut_their_windows(proto):
    cam, masks, covs = proto
    black = [1, 5, 6, 12]
    stack = masks.copy()
    stack[black] = 0.0
    # the shut windows are left out (w = 0 on a row with no open segment trips extent());
    # kernel_from_trajectory normalises over the open time that remains
    segs = [g for i, g in enumerate(pinhole_segments(cam, 0.5)) if i not in black]
    ref = kernel_from_trajectory(segs, cam.r_px, du_px=0.004)
    k = bitmap_kernel(stack, PITCH, BETA, T, 0.5, size=ref.shape, origin="pinhole")
    assert_valid(k)
    weights = np.where(np.isin(np.arange(16), black), 0.0, 1.0)
    assert l1(k, ref) <= raster_bound(stack, cam, 0.5, weights, covs) + 1e-6
    # the open patterns alone, not the closed windows' times, set the kernel
    full = bitmap_kernel(masks, PITCH, BETA, T, 0.5, size=ref.shape, origin="pinhole")
    assert l1(k, full) > 0.1
    # an all-black t = 0 pattern has no t0 image
    stack[8] = 0.0
    with pytest.raises(ParameterError, match="origin.*black"):
        bitmap_kernel(stack, PITCH, BETA, T, 0.5)
    assert np.isnan(bitmap_offsets_px(stack, PITCH, BETA)[black]).all()


def test_static_full_disc_is_the_pillbox():
    cam = designed(np.zeros((4, 2)))
    masks = discs_of(cam, shape=(320, 320))
    k = bitmap_kernel(masks, PITCH, BETA, T)
    ref = pillbox_psf(abs(BETA) * cam.R_mm, size=k.shape)
    bound = raster_bound(masks, cam, 0.0)
    assert l1(k, ref) <= bound < 1e-3


def test_large_speed_is_the_box_of_a_still_disc():
    cam = designed(np.zeros((4, 2)))
    masks = discs_of(cam, shape=(320, 320))
    s = 8.0  # a 360 px sweep
    k = bitmap_kernel(masks, PITCH, BETA, T, s)
    assert_valid(k)
    ref = static_psf(s, T, abs(BETA) * cam.R_mm, size=k.shape)
    assert l1(k, ref) <= raster_bound(masks, cam, s) + 1e-5  # static_psf: du = 0.05 quadrature
    with pytest.raises(ParameterError, match="size"):  # a 2250 px sweep does not fit 2049 px
        bitmap_kernel(masks, PITCH, BETA, T, 50.0)


# --- geometry and sign conventions ---------------------------------------------------------------


def pixel_overlap(lo, hi, n):
    """Length of [lo, hi) inside each of the n kernel pixels along one axis (independent)."""
    e = np.arange(n + 1) - n // 2 - 0.5
    return np.clip(np.minimum(hi, e[1:]) - np.maximum(lo, e[:-1]), 0.0, None)


@pytest.mark.parametrize("beta", [BETA, -60.0, 173.0])
def test_single_lcos_pixel_is_its_image_square(beta):
    h, w, i, j = 8, 10, 2, 7
    masks = np.zeros((3, h, w))
    masks[1, i, j] = 1.0
    X, Y = (j + 0.5 - w / 2) * PITCH, (i + 0.5 - h / 2) * PITCH
    u, v, b = beta * X, beta * Y, abs(beta) * PITCH
    k = bitmap_kernel(masks, PITCH, beta, T, size=15, origin="pinhole")
    assert_valid(k)
    ref = np.outer(pixel_overlap(v - b / 2, v + b / 2, 15), pixel_overlap(u - b / 2, u + b / 2, 15))
    np.testing.assert_allclose(k, ref / ref.sum(), atol=1e-13)
    if b < 0.1:  # the prototype: a point at beta (X, Y), inside one pixel
        assert k[round(v) + 7, round(u) + 7] == 1.0
    np.testing.assert_allclose(bitmap_offsets_px(masks, PITCH, beta)[1], [u, v], rtol=1e-12)


def brute(masks, pitch, beta, s, v, size, n_sub, n_t, rng):
    """Stratified sampling: n_sub^2 jittered points per LCoS pixel x n_t jittered times."""
    n, h, w = masks.shape
    te = np.linspace(-T, T, n + 1)
    e = np.arange(size + 1) - size // 2 - 0.5
    out = np.zeros((size, size))
    off = (np.arange(n_sub) + 0.5) / n_sub - 0.5
    for p in range(n):
        ii, jj = np.nonzero(masks[p])
        X = ((jj + 0.5 - w / 2)[:, None, None] + off[None, None, :]) * pitch
        Y = ((ii + 0.5 - h / 2)[:, None, None] + off[None, :, None]) * pitch
        U = np.broadcast_to(beta * X, (ii.size, n_sub, n_sub)).reshape(-1)
        V = np.broadcast_to(beta * Y, (ii.size, n_sub, n_sub)).reshape(-1)
        wt = np.repeat(masks[p][ii, jj], n_sub * n_sub)
        jit = abs(beta) * pitch / n_sub
        dt = (te[p + 1] - te[p]) / n_t
        for t in te[p] + (np.arange(n_t) + rng.uniform(0, 1, n_t)) * dt:
            ju, jv = rng.uniform(-0.5, 0.5, (2, U.size)) * jit
            out += np.histogram2d(V + jv + v * t, U + ju + s * t, bins=[e, e], weights=wt)[0]
    return out / out.sum()


@pytest.mark.parametrize("s, v", [(0.3, 0.0), (-0.2, 0.15)])
def test_random_grey_stack_against_brute_force(s, v):
    rng = np.random.default_rng(5)
    masks = rng.uniform(0, 1, (4, 6, 8)) * (rng.uniform(0, 1, (4, 6, 8)) > 0.3)
    k = bitmap_kernel(masks, PITCH, -60.0, T, s, size=31, v_px_per_ms=v, du_px=0.01,
                      origin="pinhole")  # fmt: skip
    ref = brute(masks, PITCH, -60.0, s, v, 31, 16, 64, rng)
    # stratified sampling at 16 x 16 x 64: its own L1 error ~ 1e-3 (2.8e-4 at 32 x 32 x 128)
    assert l1(k, ref) < 3e-3
    assert l1(k, np.roll(ref, 1, axis=1)) > 0.1  # one pixel off would be seen


def test_opening_to_the_right_moves_the_far_kernel_left():
    c = 2.0  # mm, design frame: right of the axis; disc_mask takes local (-x) coordinates
    mask = disc_mask((-c, 0.0), 1.0, SHAPE, PITCH, 4)
    cols = np.flatnonzero(mask.any(axis=0))
    assert cols.min() > SHAPE[1] / 2  # the opening is in the display's right half
    k = bitmap_kernel(mask, PITCH, BETA, T, origin="pinhole")
    xs = np.arange(k.shape[1]) - k.shape[1] // 2
    centroid = float((k.sum(axis=0) * xs).sum())
    assert centroid < -1.5  # beta < 0: the image moves left
    h, w = SHAPE
    X = (((mask.sum(axis=0)) * (np.arange(w) + 0.5 - w / 2)).sum() / mask.sum()) * PITCH
    assert centroid == pytest.approx(BETA * X, abs=0.01)  # pixel binning of a 1 px disc
    assert bitmap_offsets_px(mask, PITCH, BETA)[0, 0] == pytest.approx(BETA * X, rel=1e-9)
    flipped = bitmap_kernel(mask, PITCH, -BETA, T, origin="pinhole")  # near side: right
    np.testing.assert_allclose(flipped, k[:, ::-1], atol=1e-13)


def test_vertical_motion_is_the_transpose():
    rng = np.random.default_rng(2)
    masks = rng.uniform(0, 1, (3, 6, 9))
    ku = bitmap_kernel(masks, PITCH, -40.0, T, 0.4, size=29, origin="pinhole")
    kv = bitmap_kernel(masks.transpose(0, 2, 1), PITCH, -40.0, T, 0.0, size=29,
                       v_px_per_ms=0.4, origin="pinhole")  # fmt: skip
    np.testing.assert_allclose(kv, ku.T, atol=1e-13)


def test_planar_motion_matches_planar_kernel(proto):
    cam, masks, _ = proto
    s, v = 0.4, 0.3
    k = bitmap_kernel(masks, PITCH, BETA, T, s, size=41, v_px_per_ms=v, du_px=0.01)
    ref = planar_kernel(designed_segments(cam, s), cam.r_px, v, size=41, step_px=0.01)
    # both quadratures are second order (< 1e-4 at 0.01 px); the rest is the rasterisation
    assert l1(k, ref) < 1e-3
    coarse = bitmap_kernel(masks, PITCH, BETA, T, s, size=41, v_px_per_ms=v)
    assert l1(coarse, k) < 1e-3  # the default step, 0.05 px


def test_in_focus_is_the_motion_box():
    masks = discs_of(designed(np.zeros((2, 2))), shape=(320, 320))
    np.testing.assert_allclose(bitmap_kernel(masks, PITCH, 0.0, T, 0.3), static_psf(0.3, T),
                               atol=1e-13)  # fmt: skip
    point = bitmap_kernel(masks, PITCH, 0.0, T)
    assert point.shape == (3, 3) and point[1, 1] == 1.0


# --- extent, lost mass, input checks -------------------------------------------------------------


def test_extent_and_lost_fraction(proto):
    cam, masks, _ = proto
    u_lo, u_hi, v_lo, v_hi = bitmap_extent_px(masks, PITCH, BETA, T, 0.5, origin="pinhole")
    te = np.linspace(-T, T, 17)  # each disc sweeps its window: pattern_edges_ms
    ends = pattern_offsets_px(cam)[:, :1] + 0.5 * np.stack([te[:-1], te[1:]], axis=1)
    assert u_lo == pytest.approx(ends.min() - cam.r_px, abs=0.02)  # an LCoS pixel: 0.014 px
    assert u_hi == pytest.approx(ends.max() + cam.r_px, abs=0.02)
    v = pattern_offsets_px(cam)[:, 1]
    assert v_lo == pytest.approx(v.min() - cam.r_px, abs=0.02)
    assert v_hi == pytest.approx(v.max() + cam.r_px, abs=0.02)
    lost, shape = bitmap_lost_fraction(masks, PITCH, BETA, T, 0.5, origin="pinhole")
    assert lost == 0.0 and shape[0] == 2 * math.ceil(max(-u_lo, u_hi) + 0.5) + 1
    full = bitmap_kernel(masks, PITCH, BETA, T, 0.5)  # t0 origin: all of it inside
    lost, shape = bitmap_lost_fraction(masks, PITCH, BETA, T, 0.5, size=(5, 11))
    (i, j), r = shape, full.shape[0] // 2
    assert shape == (5, 11) and lost > 0.1
    assert lost == pytest.approx(
        1 - full[r - i // 2 : r + i // 2 + 1, r - j // 2 : r + j // 2 + 1].sum()
    )
    with pytest.warns(PSFTruncationWarning) as caught:
        bitmap_kernel(masks, PITCH, BETA, T, 0.5, size=(5, 11), max_lost=1.0)
    assert caught[0].message.lost == pytest.approx(lost, abs=1e-12)
    with pytest.raises(ParameterError, match=r"outside the 5x11 kernel.*size"):
        bitmap_kernel(masks, PITCH, BETA, T, 0.5, size=(5, 11))


def test_huge_beta_is_refused_quickly(proto):
    _, masks, _ = proto
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match=r"% of the PSF falls outside.*size"):
        bitmap_kernel(masks, PITCH, -1e5, T)
    assert time.perf_counter() - t0 < 2.0
    assert bitmap_lost_fraction(masks, PITCH, -1e5, T)[0] > 0.99


def test_bad_stacks_are_refused():
    good = np.zeros((2, 4, 4))
    good[0, 1, 2] = 1.0
    with pytest.raises(ParameterError, match="masks.*black"):
        bitmap_kernel(np.zeros((3, 4, 4)), PITCH, BETA, T)
    nan = good.copy()
    nan[1, 0, 0] = np.nan
    with pytest.raises(ParameterError, match="masks.*finite"):
        bitmap_kernel(nan, PITCH, BETA, T)
    with pytest.raises(ParameterError, match="masks.*finite"):
        bitmap_offsets_px(nan, PITCH, BETA)
    with pytest.raises(ParameterError, match=r"masks.*\[0, 1\]"):
        bitmap_kernel(good * 2, PITCH, BETA, T)
    with pytest.raises(ParameterError, match="masks"):
        bitmap_kernel(np.ones(5), PITCH, BETA, T)
    for name, kwargs in [("s", {"s": np.inf}), ("T_ms", {"T_ms": 0.0}), ("origin", {"origin": "x"}),
                         ("du_px", {"du_px": 0.0, "s": 1.0, "v_px_per_ms": 1.0})]:  # fmt: skip
        args = {"T_ms": T, **kwargs}
        with pytest.raises(ParameterError, match=name):
            bitmap_kernel(good, PITCH, BETA, origin=args.pop("origin", "t0"), **args)
    with pytest.raises(ParameterError, match="du_px"):  # bounded work: 16 x 4e5 steps
        bitmap_kernel(good, PITCH, BETA, T, s=8.0, v_px_per_ms=8.0, du_px=1e-4)
    with pytest.raises(ParameterError, match="pitch_mm"):
        bitmap_kernel(good, 0.0, BETA, T)
    with pytest.raises(ParameterError, match="beta_px_per_mm"):
        bitmap_kernel(good, PITCH, np.nan, T)


def test_code_values_and_single_mask():
    rng = np.random.default_rng(3)
    codes = rng.integers(0, 256, (2, 6, 6), dtype=np.uint8)
    k8 = bitmap_kernel(codes, PITCH, -50.0, T, 0.2, size=15)
    kf = bitmap_kernel(codes / 255.0, PITCH, -50.0, T, 0.2, size=15)
    np.testing.assert_allclose(k8, kf, atol=1e-7)  # float32 code values
    one = bitmap_kernel(codes[0] / 255.0, PITCH, -50.0, T, 0.2, size=15)
    two = bitmap_kernel(np.stack([codes[0] / 255.0] * 2), PITCH, -50.0, T, 0.2, size=15)
    np.testing.assert_allclose(one, two, atol=1e-13)  # (H, W): one pattern, whole exposure


def test_prototype_display_is_fast():
    cam = designed()
    masks = discs_of(cam, shape=(1024, 1280), supersample=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bitmap_kernel(masks, PITCH, BETA, T, 0.5)  # warm-up
        t0 = time.perf_counter()
        k = bitmap_kernel(masks, PITCH, BETA, T, 0.5)
        elapsed = time.perf_counter() - t0
    assert_valid(k)
    assert elapsed < 1.0  # measured 30-90 ms on one shared core
