"""Diffraction as a post-process of rendered images, and the must-show edge MTF (issue 36):
an in-focus slanted edge at F9.85 in green, its MTF with diffraction over its MTF without
against the circular pupil's MTF, within 0.03 from 0.05 to 0.45 cycles/px."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.camera import prototype
from pacam_render.model.modes import capture_camera
from pacam_render.wave.edge_mtf import edge_mtf
from pacam_render.wave.image import diffract_capture, diffract_image
from pacam_render.wave.otf import disc_otf
from pacam_render.wave.patterns import channel_wavelengths_nm, pattern_kernels
from pacam_render.wave.pupil import DiscPupil
from pacam_render.wave.reference import circular_mtf
from pacam_render.wave.scale import scale_for
from pacam_render.wave.supersampled import supersampled_capture

Q, N, SLOPE, X0 = 8, 128, 1 / 16, 40.0
NU = np.linspace(0.05, 0.45, 17)


def slanted_bar(n: int = N, q: int = Q, slope: float = SLOPE, x0: float = X0) -> np.ndarray:
    """A periodic bright bar, left edge at x = x0 + y slope (pixel-centre coordinates), on a
    grid q times finer than the pixels; each fine cell holds its covered fraction."""
    ss = 4
    c = (np.arange(n * q * ss) + 0.5) / (q * ss) - 0.5  # sub-cell centres, px
    y, x = c[:, None], c[None, :]
    u = np.mod(x - x0 - y * slope, n)
    inside = ((u > 0) & (u < n / 2)).astype(float)
    return inside.reshape(n * q, ss, n * q, ss).mean(axis=(1, 3))


@pytest.fixture(scope="module")
def normal_green():
    """The prototype's normal capture (F9.85, focused on the object) in green (549 nm)."""
    cam = capture_camera(prototype(), "normal")
    assert cam.r_px == pytest.approx(0.0, abs=1e-9)
    scale = scale_for(cam, channel_wavelengths_nm(3)[1])
    return cam, scale, disc_otf(DiscPupil(cam.R_mm), scale)


@pytest.fixture(scope="module")
def edges(normal_green):
    cam, scale, otf = normal_green
    fine = slanted_bar()
    return supersampled_capture(fine, Q), supersampled_capture(fine, Q, otf.grid)


def mtf_ratio(with_, without):
    angle = np.degrees(np.arctan(SLOPE))
    return edge_mtf(with_, angle, X0, NU) / edge_mtf(without, angle, X0, NU)


def test_diffraction_before_the_pixel_gives_the_circular_mtf(normal_green, edges):
    """The reference itself (diffraction applied before pixel integration, 8x finer)."""
    cam, scale, _ = normal_green
    geometric, exact = edges
    want = circular_mtf(NU, scale.lambda_n_px(cam.R_mm))
    assert np.max(np.abs(mtf_ratio(exact, geometric) - want)) < 0.01


def test_the_post_process_gives_the_circular_mtf(normal_green, edges):
    """The must-show, on a synthetic capture: the geometric capture convolved with the green
    channel's band kernel (the post-process), against the geometric capture."""
    cam, scale, _ = normal_green
    geometric, exact = edges
    (band,) = pattern_kernels(cam, "normal", channel_wavelengths_nm(3)[1])
    post = diffract_image(geometric, band.kernel)
    want = circular_mtf(NU, scale.lambda_n_px(cam.R_mm))
    assert np.max(np.abs(mtf_ratio(post, geometric) - want)) < 0.03
    inner = (slice(40, -40), slice(40, -40))
    assert np.sqrt(np.mean((post - exact)[inner] ** 2)) < 0.006  # vs 0.03 without diffraction
    # the pixel-integrated kernel would integrate over the pixel twice: an extra sinc
    (pixel,) = pattern_kernels(cam, "normal", 549.0, sampling="pixel")
    twice = mtf_ratio(diffract_image(geometric, pixel.kernel), geometric)
    assert np.max(np.abs(twice - want)) > 0.06


def test_diffract_image_per_channel():
    img = np.random.default_rng(0).uniform(0, 1, (20, 30, 3))
    ks = [np.ones((1, 1)), np.full((3, 3), 1 / 9), np.ones((1, 5)) / 5]
    out = diffract_image(img, ks)
    assert out.shape == img.shape
    assert np.allclose(out[..., 0], img[..., 0], rtol=0, atol=1e-12)
    assert out[5:-5, 5:-5].mean(axis=(0, 1)) == pytest.approx(
        img[5:-5, 5:-5].mean(axis=(0, 1)), abs=0.02
    )
    with pytest.raises(ParameterError, match="one per channel"):
        diffract_image(img, ks[:2])
    with pytest.raises(ParameterError, match="odd sides"):
        diffract_image(img[..., 0], np.ones((2, 2)))


def test_a_bitmap_schedule_has_a_kernel_per_window():
    from pacam_render.model.masks import MaskStack, disc_masks

    cam = prototype().with_(n_patterns=4)
    m = disc_masks(cam.pattern_centres_xy_mm(), cam.R_mm, pitch_mm=0.01362)
    m[1] = 0.0
    stack = MaskStack(m, 0.01362)
    ks = pattern_kernels(cam.with_(pattern_masks=stack), "coded", 550.0)
    assert len(ks) == 4 and ks[1] is None and all(k is not None for k in (ks[0], ks[2], ks[3]))
    assert len(pattern_kernels(cam, "coded", 550.0)) == 1  # discs: one for the exposure
    with pytest.raises(ParameterError, match="n_channels must be 1"):
        channel_wavelengths_nm(2)


def test_diffract_capture_by_channel_and_by_window():
    from pacam_render.model.masks import MaskStack, disc_masks

    cam = capture_camera(prototype(), "normal")
    img = np.random.default_rng(2).uniform(0, 1, (40, 50, 3))
    out = diffract_capture(img, cam, "normal", max_lost=0.01)
    for c, w in enumerate(channel_wavelengths_nm(3)):
        (k,) = pattern_kernels(cam, "normal", w, max_lost=0.01)
        assert np.allclose(out[..., c], diffract_image(img[..., c], k.kernel), atol=1e-12)
    coded = prototype().with_(n_patterns=2)
    m = disc_masks(coded.pattern_centres_xy_mm(), coded.R_mm, pitch_mm=0.01362)
    m[0] = 0.0
    bitmap = coded.with_(pattern_masks=MaskStack(m, 0.01362))
    with pytest.raises(ParameterError, match="window_images.*2 pattern windows"):
        diffract_capture(img, bitmap, "coded")
    windows = [0.3 * img, 0.7 * img]
    got = diffract_capture(img, bitmap, "coded", window_images=windows, max_lost=0.01)
    (_, k1) = pattern_kernels(bitmap, "coded", 549.0, max_lost=0.01)
    assert np.allclose(got[..., 1], diffract_image(windows[1][..., 1], k1.kernel), atol=1e-12)
