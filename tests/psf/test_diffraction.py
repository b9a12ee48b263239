"""The diffraction factor of the analytic model, and the error of the defocus + diffraction
combination against the exact Fourier-optics PSF (issue 36)."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.camera import prototype
from pacam_render.model.masks import MaskStack, disc_masks
from pacam_render.model.modes import MODES_WITH_PSF, capture_camera
from pacam_render.psf.analytic import design_psf
from pacam_render.psf.combination import combination_error
from pacam_render.psf.diffraction import convolve_kernels, crop_centred, with_diffraction
from pacam_render.wave.fraunhofer import fraunhofer_kernel
from pacam_render.wave.patterns import CHANNEL_WAVELENGTHS_NM, mode_diffraction_kernel
from pacam_render.wave.pupil import DiscPupil, mask_pupil
from pacam_render.wave.scale import DiffractionScale, scale_for

LCOS = 0.01362
S550 = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * LCOS)
R9 = 145.5 * LCOS

COMBINATION_L1 = {  # r px: (l1_simulator, l1_continuous), benchmarks/RESULTS.md
    0.0: (0.0, 0.0),
    0.5: (0.0880, 0.2124),
    1.0: (0.4996, 0.4926),
    2.0: (0.3569, 0.3672),
    4.0: (0.3505, 0.3606),
}
"""The tabulated L1 of the combinations to the exact PSF at F9.85, 550 nm, 81 px kernels."""
MARGIN = 0.005


@pytest.mark.parametrize("r", sorted(COMBINATION_L1))
def test_the_combination_error_does_not_grow(r):
    e = combination_error(R9, r, S550)
    simulator, continuous = COMBINATION_L1[r]
    assert e["l1_simulator"] <= simulator + MARGIN
    assert e["l1_continuous"] <= continuous + MARGIN
    assert e["l1_geometric"] > e["l1_simulator"]  # diffraction helps at every r
    if r == 0.0:
        assert e["l1_simulator"] < 1e-12  # in focus the combination is exact


@pytest.mark.parametrize("mode", MODES_WITH_PSF)
def test_the_default_kernel_is_unchanged_and_diffraction_counts_the_pixel_once(mode):
    """None keeps the geometric kernel bit for bit. With a wavelength the kernel has the full
    convolution's shape, sums to 1 and is non-negative, and lies within a few percent (L1) of
    the geometric kernel convolved with the pixel-integrated Airy kernel, which counts the
    pixel's box twice (0.017 coded, 0.075 flutter at 0.3 px/ms; the rendered PSFs in
    tests/psf_render/test_psf_render.py tell the two apart)."""
    cam = capture_camera(prototype(), mode)
    geometric = design_psf(cam, mode, 0.3)
    assert np.array_equal(design_psf(cam, mode, 0.3, diffraction_nm=None), geometric)
    k = design_psf(cam, mode, 0.3, diffraction_nm=549.0)
    d = mode_diffraction_kernel(cam, mode, 549.0).kernel
    assert k.shape == tuple(np.add(geometric.shape, d.shape) - 1)
    assert k.sum() == pytest.approx(1.0, abs=1e-12) and k.min() >= 0.0
    twice = convolve_kernels(geometric, d)
    bound = 0.1 if mode == "flutter" else 0.03  # its chopped streak has the sharpest edges
    assert np.abs(k - twice / twice.sum()).sum() < bound


def test_in_focus_the_normal_kernel_is_the_airy_pattern():
    """A still point in focus (r = 0): the kernel is the pixel-integrated Airy pattern at the
    opening's F-number (F9.85)."""
    cam = capture_camera(prototype(), "normal")
    assert cam.r_px == pytest.approx(0.0, abs=1e-9) and cam.F_number == pytest.approx(
        9.853, abs=1e-3
    )
    k = design_psf(cam, "normal", 0.0, diffraction_nm=550.0)
    airy = fraunhofer_kernel(DiscPupil(cam.R_mm), scale_for(cam, 550.0)).kernel
    # built on finer pixels and binned: the same integrals (the rings from the coarse kernel)
    inner = crop_centred(k, airy.shape)
    assert np.abs(inner / inner.sum() - airy).sum() < 1e-4
    # the 1 px ring outside the Airy kernel's 153 px holds ~ 2 lambda N / (pi^2 rho) x (1 px
    # / rho) of the light: 3e-5 at rho = 76 px
    assert 1e-5 < 1.0 - inner.sum() < 5e-5


def test_colour_channels_diffract_with_their_wavelengths():
    cam = capture_camera(prototype(), "normal")
    peaks = [mode_diffraction_kernel(cam, "normal", w).kernel.max() for w in CHANNEL_WAVELENGTHS_NM]
    assert peaks[0] < peaks[1] < peaks[2]  # red spreads most, blue least
    assert CHANNEL_WAVELENGTHS_NM == (611.0, 549.0, 464.0)


def test_a_bitmap_schedule_weights_its_patterns_by_open_area():
    """Per-pattern kernels weighted by open area x time; black patterns pass nothing."""
    cam = prototype().with_(n_patterns=4)
    m = disc_masks(cam.pattern_centres_xy_mm(), cam.R_mm, pitch_mm=LCOS)
    m[1] = 0.0  # closed during one window
    m[2] = disc_masks(cam.pattern_centres_xy_mm()[2:3], 0.5 * cam.R_mm, pitch_mm=LCOS)[0]
    stack = MaskStack(m, LCOS)
    bitmap = cam.with_(pattern_masks=stack, R_mm=stack.equivalent_radius_mm())
    got = mode_diffraction_kernel(bitmap, "coded", 550.0)
    scale = scale_for(bitmap, 550.0)
    n = got.kernel.shape[0]  # each pattern's own kernel at that size, weighted by its light
    parts = [(fraunhofer_kernel(mask_pupil(m[k], LCOS), scale, size=n, max_lost=0.5), m[k].sum())
             for k in (0, 2, 3)]  # fmt: skip
    want = sum(w * d.kernel for d, w in parts) / sum(w for _, w in parts)
    # equal but for each kernel's own renormalisation over the light it leaves out (<= 0.2 %)
    lost = max(d.lost for d, _ in parts)
    assert np.abs(got.kernel - want).sum() <= 2 * lost + 1e-12
    assert got.lost <= 2e-3 and np.isclose(got.kernel.sum(), 1.0)
    # normal mode opens the equivalent disc: one Airy kernel
    normal = capture_camera(bitmap, "normal")
    airy = fraunhofer_kernel(DiscPupil(normal.R_mm), scale).kernel
    assert np.array_equal(mode_diffraction_kernel(normal, "normal", 550.0).kernel, airy)


def test_the_parabola_of_lcos_discs_diffracts_like_the_ideal_disc():
    cam = prototype()
    m = disc_masks(cam.pattern_centres_xy_mm(), cam.R_mm, pitch_mm=LCOS)
    bitmap = cam.with_(pattern_masks=MaskStack(m, LCOS))
    got = mode_diffraction_kernel(bitmap, "coded", 550.0).kernel
    ideal = fraunhofer_kernel(DiscPupil(cam.R_mm), scale_for(cam, 550.0), size=got.shape[0]).kernel
    assert np.abs(got - ideal).sum() < 5e-3


def test_the_reference_has_no_aperture():
    with pytest.raises(ParameterError, match="pinhole.*no aperture"):
        mode_diffraction_kernel(prototype(), "reference", 550.0)


def test_a_cropped_kernel_warns_with_its_lost_light():
    from pacam_render.psf.grid import PSFTruncationWarning

    cam = prototype()
    with pytest.warns(PSFTruncationWarning, match="outside the 21x21 kernel"):
        k = with_diffraction(design_psf(cam, "coded"), cam, "coded", 550.0, size=21)
    assert k.shape == (21, 21) and k.sum() == pytest.approx(1.0)


def test_a_one_lcos_pixel_opening_is_refused_for_a_design():
    cam = prototype().with_(R_mm=LCOS)  # the smallest opening the display can show
    with pytest.raises(ParameterError, match=r"needs about \d+ px.*max_lost"):
        design_psf(capture_camera(cam, "normal"), "normal", diffraction_nm=550.0)


@pytest.mark.parametrize("mode", ["coded", "flutter"])
def test_the_default_fine_grid_converges(mode):
    """The box-once kernel at its default fine grid (supersample: fine pixels <= lambda N / 7)
    against the same kernel on pixels 21x finer, near the continuous limit (the error falls as
    the fine pixel squared): within L1 1e-3 at F9.85, where a fixed 3x grid is 4e-3 (coded,
    r = 2 px) and 9e-3 (the fluttered shutter's in-focus chopped streak) away."""
    from pacam_render.psf.diffraction import diffracted_kernel, supersample
    from pacam_render.wave.patterns import mode_cutoff

    cam = capture_camera(prototype(), mode)
    lam_n_px = 549e-6 * cam.F_number / cam.pixel_pitch_mm
    assert mode_cutoff(cam, mode, 549.0) == pytest.approx(1.0 / lam_n_px, rel=1e-9)
    f = supersample(cam, mode, 549.0)
    assert f % 2 == 1 and 1.0 / f <= lam_n_px / 7.0 < 1.0 / (f - 2)
    shape = design_psf(cam, mode, 0.4).shape

    def build(c, k, fine):
        return design_psf(c, mode, 0.4 * k, fine)

    ref = diffracted_kernel(build, cam, mode, 549.0, shape, factor=21)
    rough = diffracted_kernel(build, cam, mode, 549.0, shape, factor=3)
    assert np.abs(diffracted_kernel(build, cam, mode, 549.0, shape) - ref).sum() < 1e-3
    assert np.abs(rough - ref).sum() > 3e-3
    for bad in (2, 0, 1.5):  # an even grid has no centre pixel
        with pytest.raises(ParameterError, match="factor must be an odd integer"):
            diffracted_kernel(build, cam, mode, 549.0, shape, factor=bad)
