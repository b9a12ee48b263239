"""The Fraunhofer kernels of pupils (pacam_render.wave) against closed forms and brute force."""

from __future__ import annotations

import time

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.masks import disc_mask
from pacam_render.wave.fraunhofer import fraunhofer_kernel, kernel_from_otf, periodic_kernel
from pacam_render.wave.otf import pupil_otf
from pacam_render.wave.pupil import DiscPupil, GridPupil, disc_pupil, mask_pupil
from pacam_render.wave.reference import (
    airy_kernel_quadrature,
    bessel_j1,
    circular_mtf,
)
from pacam_render.wave.scale import DiffractionScale

PITCH = 0.00645
LCOS = 0.01362
D = 2 * 2.8 * 512 * LCOS  # the pupil distance of the paper's F-number scale
R9 = 145.5 * LCOS  # the F9.85 opening
S550 = DiffractionScale(550.0, PITCH, D)


def dtft_rows(k: np.ndarray, nu: np.ndarray) -> np.ndarray:
    """The kernel's transfer function along x (nu_y = 0): its column sums' DTFT."""
    m = np.arange(k.shape[1]) - k.shape[1] // 2
    return np.abs(np.exp(-2j * np.pi * np.outer(nu, m)) @ k.sum(axis=0))


def test_bessel_j1_against_scipy():
    special = pytest.importorskip("scipy.special")
    x = np.concatenate([np.linspace(-30, 30, 4001), np.geomspace(24.0, 1e5, 4001)])
    assert np.max(np.abs(bessel_j1(x) - special.j1(x))) < 2e-15


def test_the_f_number_scale_of_the_paper():
    assert S550.f_number(512 * LCOS) == pytest.approx(2.8)
    assert S550.f_number(R9) == pytest.approx(9.852, abs=1e-3)
    assert S550.airy_first_zero_px(R9) == pytest.approx(1.02, abs=0.005)  # issue 36
    assert S550.airy_first_zero_px(512 * LCOS) == pytest.approx(0.29, abs=0.005)
    assert circular_mtf(0.5, S550.lambda_n_px(R9)) == pytest.approx(0.48, abs=0.01)
    assert circular_mtf(0.5, S550.lambda_n_px(512 * LCOS)) == pytest.approx(0.85, abs=0.01)


def test_the_disc_kernel_is_the_pixel_integrated_airy_pattern():
    """Against Gauss-Legendre quadrature of the closed-form Airy pattern (no shared code): the
    light inside the window agrees to the stated alias estimate."""
    d = fraunhofer_kernel(DiscPupil(R9), S550, size=41, max_lost=0.02)
    ref = airy_kernel_quadrature(S550.lambda_n_px(R9), 41)
    inside = d.kernel * (1.0 - d.lost)  # the kernel before renormalisation
    assert np.abs(inside - ref).sum() < max(d.alias, 1e-6)
    assert d.lost == pytest.approx(1.0 - ref.sum(), abs=d.alias)
    assert d.kernel.sum() == pytest.approx(1.0, abs=1e-12)
    assert inside[20, 20] == pytest.approx(0.642, abs=1e-3)  # 64 % in the centre pixel


def test_the_first_dark_ring_is_at_1_22_lambda_n():
    """On pixels 16 times finer the radial profile's first minimum is 1.22 lambda N (1.02 px
    at F9.85, 550 nm, 6.45 um)."""
    fine = DiffractionScale(550.0, PITCH / 16, D)
    k = fraunhofer_kernel(DiscPupil(R9), fine, size=61, max_lost=0.5).kernel
    row = k[30, 30:]
    first_min = int(np.argmax(np.diff(row) > 0))  # first index where the profile rises
    assert first_min / 16 == pytest.approx(1.02, abs=1.0 / 16)


@pytest.mark.parametrize("sampling", ["pixel", "band"])
def test_the_kernel_mtf_is_the_circular_pupil_mtf(sampling):
    """'band': the transfer function is H(nu) on |nu| < 1/2; 'pixel': H(nu) sinc(nu) summed
    over the aliases nu + k (Poisson). Both within 2 lost + alias (truncation, aliasing)."""
    ln = S550.lambda_n_px(R9)
    d = fraunhofer_kernel(DiscPupil(R9), S550, sampling=sampling)
    nu = np.linspace(0.0, 0.49, 50)
    got = dtft_rows(d.kernel, nu)
    if sampling == "band":
        want = circular_mtf(nu, ln)
    else:
        want = sum(circular_mtf(nu + j, ln) * np.sinc(nu + j) for j in range(-3, 4))
    assert np.max(np.abs(got - want)) < 2 * d.lost + d.alias
    assert d.lost <= 0.002


def test_energy_is_conserved():
    """The periodic sum holds exactly the pupil's light (H(0) = 1); the kernel and its lost
    light add up to it."""
    ring = np.zeros((40, 50))
    ring[5:35, 5:45] = 1.0
    ring[15:25, 20:30] = 0.3  # a grey hole
    for pupil in (DiscPupil(R9), disc_pupil(R9, 32), mask_pupil(ring, LCOS)):
        otf = pupil_otf(pupil, S550)
        assert periodic_kernel(otf, 256).sum() == pytest.approx(1.0, abs=1e-12)
        d = kernel_from_otf(otf, size=61, max_lost=0.5)
        k = periodic_kernel(otf, d.period_px)
        c = d.period_px // 2
        assert k[c - 30 : c + 31, c - 30 : c + 31].sum() == pytest.approx(1 - d.lost, abs=1e-12)


def test_a_bitmap_kernel_is_exact_against_brute_force():
    """A small grey L-shaped bitmap (not symmetric): |FT|^2 summed cell by cell (sinc envelope x
    explicit DFT) and integrated over each pixel by Gauss-Legendre quadrature. This checks the
    exact bilinear OTF, the scale (lambda D / p) and the orientation (rows stay rows). The
    only difference is aliasing, within the stated estimate, and it falls as the period grows
    (3.3e-3, 8.0e-4, 2.1e-4 at L = 405, 810, 1620 px)."""
    h, w, n, q = 16, 24, 101, 6
    tau = np.outer(np.linspace(0.2, 1.0, h), np.linspace(1.0, 0.5, w))
    tau[:8, 12:] = 0.0  # an L: no symmetry to hide a flipped axis
    d = fraunhofer_kernel(mask_pupil(tau, LCOS), S550, size=n, max_lost=0.2)
    g, gw = np.polynomial.legendre.leggauss(q)
    pts = ((np.arange(n) - n // 2)[:, None] + 0.5 * g[None, :]).ravel()  # px
    wts = np.tile(0.5 * gw, n)
    lam_d = S550.wavelength_mm * D
    f = pts * PITCH / lam_d  # the pupil-plane frequency each image point probes, cycles/mm
    env = LCOS * np.sinc(LCOS * f)  # one LCoS pixel's transform
    ex = np.exp(-2j * np.pi * np.outer((np.arange(w) - w / 2 + 0.5) * LCOS, f)) * env
    ey = np.exp(-2j * np.pi * np.outer((np.arange(h) - h / 2 + 0.5) * LCOS, f)) * env
    field = ey.T @ np.sqrt(tau) @ ex  # rows: image y, columns: image x
    dens = np.abs(field) ** 2 * PITCH**2 / (lam_d**2 * np.sum(tau) * LCOS**2)  # per px^2
    brute = ((wts[:, None] * dens * wts[None, :]).reshape(n, q, n, q)).sum(axis=(1, 3))
    assert np.abs(d.kernel * (1 - d.lost) - brute).sum() < max(d.alias, 1e-5)
    big = periodic_kernel(pupil_otf(mask_pupil(tau, LCOS), S550), 4 * d.period_px)
    c = 2 * d.period_px
    assert np.abs(big[c - 50 : c + 51, c - 50 : c + 51] - brute).sum() < 3e-4  # aliasing ~ L^-2
    assert not np.allclose(d.kernel, d.kernel.T, atol=1e-4)  # the test can see a transpose


def test_a_wide_opening_diffracts_narrowly_along_its_width():
    slit = np.zeros((3, 60))
    slit[1] = 1.0  # one display row, 60 columns: wide along the image's x
    k = fraunhofer_kernel(mask_pupil(slit, LCOS), S550, size=201, max_lost=0.5).kernel
    spread = lambda p: float(np.sum(p * np.abs(np.arange(201) - 100)))  # noqa: E731
    assert spread(k.sum(axis=0)) < 0.1 * spread(k.sum(axis=1))


def test_a_shifted_opening_has_the_same_kernel():
    """|FT|^2 does not see where the opening is (shift theorem): a disc moved by whole LCoS
    pixels gives the same kernel; moved by a fraction, it rasterises differently (small)."""
    base = fraunhofer_kernel(mask_pupil(disc_mask((0.0, 0.0), R9), LCOS), S550).kernel
    moved = fraunhofer_kernel(mask_pupil(disc_mask((40 * LCOS, -7 * LCOS), R9), LCOS), S550)
    assert np.abs(moved.kernel - base).max() < 1e-13
    sub = fraunhofer_kernel(mask_pupil(disc_mask((0.3 * LCOS, 0.0), R9), LCOS), S550).kernel
    n = min(sub.shape[0], base.shape[0])
    crop = lambda k: k[(k.shape[0] - n) // 2 :][:n, (k.shape[0] - n) // 2 :][:, :n]  # noqa: E731
    assert np.abs(crop(sub) - crop(base)).sum() < 5e-3
    ideal = fraunhofer_kernel(DiscPupil(R9), S550, size=n).kernel
    assert np.abs(crop(base) - ideal).sum() < 5e-3  # the LCoS's staircase disc vs the ideal


@pytest.mark.parametrize(("n", "bound"), [(64, 4e-3), (128, 1e-3)])
def test_a_sampled_disc_converges_to_the_airy_pattern(n, bound):
    ideal = fraunhofer_kernel(DiscPupil(R9), S550, size=41, max_lost=0.05).kernel
    got = fraunhofer_kernel(disc_pupil(R9, n), S550, size=41, max_lost=0.05).kernel
    assert np.abs(got - ideal).sum() < bound


def test_one_lcos_pixel_is_refused_clearly_and_cheaply():
    """Diffraction far larger than the geometry: its central lobe is 2 x 244 px wide at
    550 nm, and 0.2 % of its light lies beyond ~50 000 px. Refused before any work, naming
    max_lost; accepted with a size and a max_lost that admit the loss (bounded time)."""
    one = np.zeros((1024, 1280))
    one[500, 600] = 1.0
    pupil = mask_pupil(one, LCOS)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match=r"needs about 4\d{4} px.*max_lost"):
        fraunhofer_kernel(pupil, S550)
    assert time.perf_counter() - t0 < 0.5
    with pytest.raises(ParameterError, match="outside the 2049 px kernel.*max_lost"):
        fraunhofer_kernel(pupil, S550, size=2049)
    d = fraunhofer_kernel(pupil, S550, size=2049, max_lost=0.1)
    assert 0.03 < d.lost < 0.06 and d.kernel.max() < 1e-4  # a very wide, faint kernel
    with pytest.raises(ParameterError, match="size must be an odd integer in"):
        fraunhofer_kernel(pupil, S550, size=2051, max_lost=0.1)


def test_a_closed_pattern_is_refused():
    for make in (
        lambda: mask_pupil(np.zeros((8, 8)), LCOS),
        lambda: GridPupil(np.zeros((3, 3)), LCOS),
    ):
        with pytest.raises(ParameterError, match="closed .*no light passes"):
            make()


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: DiffractionScale(200.0, PITCH, D), r"wavelength_nm must be in \[300, 1100\]"),
        (lambda: DiffractionScale(550.0, 0.0, D), "pixel_pitch_mm must be > 0"),
        (lambda: fraunhofer_kernel(DiscPupil(R9), S550, size=40), "size must be an odd"),
        (lambda: fraunhofer_kernel(DiscPupil(R9), S550, max_lost=0.0), r"max_lost must be in"),
        (lambda: fraunhofer_kernel(DiscPupil(R9), S550, sampling="x"), "sampling must be one"),
        (lambda: DiscPupil(-1.0), "radius_mm must be > 0"),
        (lambda: mask_pupil(np.full((2, 2), 2.0), LCOS), r"mask: transmittance must be in"),
        (lambda: disc_pupil(R9, 1), "samples_per_radius must be an integer >= 2"),
    ],
)
def test_bad_parameters_name_themselves(call, match):
    with pytest.raises(ParameterError, match=match):
        call()
