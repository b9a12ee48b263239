"""Analytic PSFs against independent references: brute-force sampling, quadrature of Eq. 1,
closed-form properties, and the stiff/extreme cases of issue 2."""

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate

from pacam_render.errors import ParameterError
from pacam_render.psf import analytic as psf
from pacam_render.psf.trajectory import Segment, density

T = 22.5
RNG = np.random.default_rng(1234)


def centre_row(k):
    return k[k.shape[0] // 2]


def x_edges(w):
    return np.arange(w + 1) - w // 2 - 0.5


def brute_motion(s, a, T, w, n=4_000_001):
    """Fraction of finely sampled times spent in each pixel column (midpoint rule in t)."""
    t = -T + (np.arange(n) + 0.5) * (2 * T / n)
    return np.histogram(s * t + 0.5 * a * t * t, bins=x_edges(w))[0] / n


def assert_valid(k):
    assert np.all(np.isfinite(k))
    assert k.min() >= 0.0
    assert k.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("s,a", [(0.0, 0.04), (0.3, 0.04), (-0.7, 0.04), (1.2, 0.04), (0.5, -0.1)])
def test_levin_matches_brute_force_sampling(s, a):
    k = psf.levin_psf(s, a, T)
    ref = brute_motion(s, a, T, k.shape[1])
    assert np.abs(centre_row(k) - ref).sum() < 2e-5
    assert not np.delete(k, k.shape[0] // 2, axis=0).any()  # horizontal motion: one row


@pytest.mark.parametrize("s", [0.0, 0.4, 0.8, 1.5])
def test_levin_matches_quadrature_of_eq1(s):
    """Integrate the (corrected) Eq. 1 density over each pixel with scipy, singularity included."""
    a = 0.04
    k = centre_row(psf.levin_psf(s, a, T))
    seg = [Segment(-T, T, 0.0, s, a)]
    e = x_edges(k.size)
    xv = -s * s / (2 * a)  # the vertex: split the integral there
    ref = []
    for lo, hi in zip(e[:-1], e[1:]):
        pts = [xv] if lo < xv < hi else None
        val, _ = integrate.quad(lambda x: density(seg, x)[()], lo, hi, points=pts, limit=200)
        ref.append(val)
    assert np.abs(k - np.array(ref)).sum() < 1e-6


def test_eq1_density_formula():
    """Where the point passes once or twice, density = lambda / (2T sqrt(s^2 + 2 a x))."""
    s, a = 0.5, 0.04
    x = np.array(
        [0.0, 3.0, 8.0, 12.0]
    )  # x(T) = 21.4, x(-T) = -1.6 => lambda = 2 on [-s^2/2a, -1.6)
    lam = np.where(x < s * -T + 0.5 * a * T * T, 2, 1)
    lam = np.where(x > s * T + 0.5 * a * T * T, 0, lam)
    expect = lam / (2 * T * np.sqrt(s * s + 2 * a * x))
    assert density([Segment(-T, T, 0.0, s, a)], x) == pytest.approx(expect, rel=1e-12)


def brute_pillbox(r, n, cx=0.0, cy=0.0, ss=500):
    g = (np.arange(n * ss) + 0.5) / ss - n / 2
    X, Y = np.meshgrid(g, g)
    m = ((X - cx) ** 2 + (Y - cy) ** 2 <= r * r).reshape(n, ss, n, ss).sum((1, 3))
    return m / m.sum()


@pytest.mark.parametrize("r,c", [(0.3, (0.0, 0.0)), (2.0, (0.0, 0.0)), (3.7, (0.25, -0.4))])
def test_pillbox_exact_coverage(r, c):
    k = psf.pillbox_psf(r, size=11, centre=c)
    assert np.abs(k - brute_pillbox(r, 11, *c)).sum() < 2e-4
    assert_valid(k)


def test_pillbox_tends_to_delta():
    k = psf.pillbox_psf(1e-6, size=5)
    assert k[2, 2] == 1.0
    k = psf.pillbox_psf(0.01, size=5)
    assert k[2, 2] == pytest.approx(1.0, abs=1e-12)


def test_pillbox_symmetry():
    k = psf.pillbox_psf(2.6, size=9)
    assert np.allclose(k, k.T, atol=1e-15) and np.allclose(k, k[::-1], atol=1e-15)
    assert np.allclose(k, k[:, ::-1], atol=1e-15)


def monte_carlo_coded(s, a, r, T, w, n=2_000_000, discrete=None):
    t = RNG.uniform(-T, T, n)
    if discrete:
        e = np.linspace(-T, T, discrete + 1)
        tk = (
            0.5
            * (e[:-1] + e[1:])[np.clip(((t + T) / (2 * T) * discrete).astype(int), 0, discrete - 1)]
        )
        x = s * t + 0.5 * a * tk * tk
    else:
        x = s * t + 0.5 * a * t * t
    rho, th = r * np.sqrt(RNG.uniform(0, 1, n)), RNG.uniform(0, 2 * np.pi, n)
    e = x_edges(w)
    h, _, _ = np.histogram2d(rho * np.sin(th), x + rho * np.cos(th), bins=[e, e])
    return h / n


@pytest.mark.parametrize("discrete", [None, 16])
def test_coded_psf_matches_monte_carlo(discrete):
    s, a, r = 0.4, 0.04, 2.0
    k = (
        psf.discrete_coded_psf(s, a, r, T, 16, size=49)
        if discrete
        else psf.coded_psf(s, a, r, T, size=49)
    )
    mc = monte_carlo_coded(s, a, r, T, 49, discrete=discrete)
    noise = np.sqrt(k / 2_000_000).sum()  # expected L1 of the MC estimate, roughly
    assert np.abs(k - mc).sum() < 2.5 * noise


def test_discrete_tends_to_continuous():
    s, a, r = 0.3, 0.04, 2.0
    cont = psf.coded_psf(s, a, r, T, size=45, du_px=0.01)
    errs = [
        np.abs(psf.discrete_coded_psf(s, a, r, T, n, size=45, du_px=0.01) - cont).sum()
        for n in (16, 64, 256)
    ]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 2e-3
    assert errs[0] / errs[1] > 8  # second order in 1/n: 16x expected


def test_discrete_at_rest_is_sum_of_16_pillboxes():
    """At s = 0 each pattern is a held pillbox: compare with 16 exact pillboxes."""
    a, r = 0.04, 2.0
    k = psf.discrete_coded_psf(0.0, a, r, T, 16, size=31)
    e = np.linspace(-T, T, 17)
    tk = 0.5 * (e[:-1] + e[1:])
    ref = sum(psf.pillbox_psf(r, size=31, centre=(0.5 * a * t * t, 0.0)) for t in tk) / 16
    assert np.abs(k - ref).sum() < 1e-12


@pytest.mark.parametrize("s", [0.1, 0.45, 0.9])
def test_invariance_is_shift_plus_tail(s):
    """Inside |s| <= a T the s-PSF is the s=0 PSF shifted by -s^2/2a plus a tail of L1 s/(aT)."""
    a = 0.04
    shifted = [Segment(-T, T, -psf.vertex_shift_px(s, a), s, a)]
    k_s = psf.kernel_from_trajectory(shifted, 0.0, size=101)
    k_0 = psf.levin_psf(0.0, a, T, size=101)
    l1 = np.abs(k_s - k_0).sum()
    bound = psf.invariance_tail_l1(s, a, T)
    assert l1 <= bound + 1e-12
    assert l1 > 0.8 * bound  # the tails barely overlap: the bound is nearly attained


def test_invariance_tail_outside_range_is_an_error():
    with pytest.raises(ParameterError, match="invariant range"):
        psf.invariance_tail_l1(1.0, 0.04, T)


def test_static_box_length():
    k = centre_row(psf.static_psf(1.0, T))
    assert np.count_nonzero(k) == 45  # |s| 2T = 45 px on integer-aligned pixels
    assert k.max() == pytest.approx(1 / 45)


def test_short_exposure_and_flutter():
    k = psf.short_exposure_psf(1.4, 0.679)
    assert k.shape == (3, 3) and k[1, 1] == 1.0  # 0.95 px of motion stays within the centre pixel
    s = 1.3
    f = centre_row(psf.flutter_psf(s, T, size=(1, 61)))
    code = np.array([int(c) for c in psf.sch.RASKAR_2006_CODE])
    assert code.size == 52 and code.sum() == 26
    n = 4_000_000
    t = -T + (np.arange(n) + 0.5) * (2 * T / n)
    open_ = code[np.minimum((t + T) / (2 * T) * 52, 51).astype(int)] == 1
    ref = np.histogram(s * t[open_], bins=x_edges(61))[0] / open_.sum()
    assert np.abs(f - ref).sum() < 2e-5


def test_levin_is_mirror_for_negative_acceleration():
    a = centre_row(psf.levin_psf(0.3, 0.05, T, size=41))
    b = centre_row(psf.levin_psf(-0.3, -0.05, T, size=41))
    assert np.allclose(a, b[::-1], atol=1e-15)


# --- stiff and extreme settings -------------------------------------------------------------
@pytest.mark.parametrize(
    "s,a,r,TT",
    [
        (0.5, 1e-14, 2.0, T),  # a_i -> 0: the box
        (0.0, 0.0, 0.0, T),  # no motion at all: a delta
        (0.3, 1e6, 2.0, T),  # a_i huge: truncated, renormalised
        (0.9, 0.04, 2.0, T),  # s exactly at the range limit
        (3.0, 0.04, 2.0, T),  # beyond it
        (0.3, 0.04, 1e-9, T),  # r << 1 px
        (0.3, 0.04, 500.0, T),  # r larger than the kernel
        (0.3, -0.04, 2.0, T),  # beta < 0
        (0.3, 0.04, 2.0, 1e-9),  # T -> 0
    ],
)
def test_extreme_cases_stay_valid(s, a, r, TT):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", psf.PSFTruncationWarning)
        kernels = [psf.coded_psf(s, a, r, TT, size=65), psf.levin_psf(s, a, TT, size=65)]
        if a < 1e3:  # with a_i huge the 16 held patterns all lie far off-kernel: a clear error
            kernels.append(psf.discrete_coded_psf(s, a, r, TT, size=65))
        for k in kernels:
            assert_valid(k)


def test_subnormal_acceleration_is_the_linear_limit():
    """a_i = 5e-324: a/2 underflows to 0; the kernel must be the a_i = 0 one, not empty."""
    for s in (0.0, 0.5):
        k = psf.coded_psf(s, 5e-324, 0.0, 1.0, size=33)
        assert_valid(k)
        assert np.abs(k - psf.static_psf(s, 1.0, size=33)).sum() < 1e-12


def test_a_to_zero_tends_to_box():
    k1 = psf.levin_psf(0.5, 1e-14, T, size=41)
    k0 = psf.static_psf(0.5, T, size=41)
    assert np.abs(k1 - k0).sum() < 1e-9


def test_huge_acceleration_warns_truncation():
    with pytest.warns(psf.PSFTruncationWarning, match="outside the 65x65 kernel"):
        k = psf.levin_psf(0.0, 1e6, T, size=65)
    assert_valid(k)
    # what is kept is the vertex: mass within 32 px of it is sqrt(2 * 32.5 / a) / T of the total
    assert k[32, 32:].sum() == pytest.approx(1.0)


def test_bad_input_names_parameter():
    with pytest.raises(ParameterError, match="r_px"):
        psf.coded_psf(0.0, 0.04, -1.0, T)
    with pytest.raises(ParameterError, match="T_ms"):
        psf.levin_psf(0.0, 0.04, 0.0)
    with pytest.raises(ParameterError, match="s"):
        psf.levin_psf(float("nan"), 0.04, T)
    with pytest.raises(ParameterError, match="enlarge size"):  # all mass off the kernel
        psf.kernel_from_trajectory([Segment(-T, T, 100.0, 0.1, 0.0)], 0.0, size=3)
    with pytest.raises(ParameterError, match="enlarge size"):  # huge a_i: every pattern far off
        psf.discrete_coded_psf(0.3, 1e6, 2.0, T, size=65)


@settings(max_examples=60, deadline=None)
@given(
    s=st.floats(-10, 10),
    a=st.floats(-1, 1),
    r=st.floats(0, 20),
    TT=st.floats(1e-6, 100),
    n=st.integers(1, 64),
)
def test_property_normalised_nonnegative(s, a, r, TT, n):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", psf.PSFTruncationWarning)
        assert_valid(psf.coded_psf(s, a, r, TT, size=33))
        try:
            assert_valid(psf.discrete_coded_psf(s, a, r, TT, n, size=33))
        except ParameterError:
            # legitimate only if every held pattern's smeared disc misses the kernel entirely
            e = np.linspace(-TT, TT, n + 1)
            tk = 0.5 * (e[:-1] + e[1:])
            centre = 0.5 * a * tk * tk + s * tk
            reach = 0.5 * abs(s) * (2 * TT / n) + r
            assert np.all(np.abs(centre) - reach > 16.5 - 1e-9)


@settings(max_examples=60, deadline=None)
@given(s=st.floats(-3, 3), a=st.floats(0.001, 0.3))
def test_property_mirror_symmetry(s, a):
    """Reversing the motion (s, a) -> (-s, -a) mirrors the PSF about x = 0."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", psf.PSFTruncationWarning)
        k1 = psf.coded_psf(s, a, 1.5, T, size=(5, 61))
        k2 = psf.coded_psf(-s, -a, 1.5, T, size=(5, 61))
    assert np.abs(k1 - k2[:, ::-1]).sum() < 1e-9


@settings(max_examples=40, deadline=None)
@given(s=st.floats(-2, 2), a=st.floats(-0.2, 0.2), TT=st.floats(0.5, 50))
def test_property_full_mass_and_first_moment(s, a, TT):
    """With the whole path inside the kernel, the centroid is the time-mean of x(t) = a T^2/6."""
    half = abs(s) * TT + 0.5 * abs(a) * TT * TT
    if half > 200:
        return
    k = centre_row(psf.levin_psf(s, a, TT))
    xc = np.arange(k.size) - k.size // 2
    # pixel-integrated centroid error is bounded by the within-pixel offset (< 0.5 px)
    assert abs((k * xc).sum() - a * TT * TT / 6) < 0.5
    assert math.isclose(k.sum(), 1.0, abs_tol=1e-12)
