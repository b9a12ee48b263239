"""Exact paraxial defocus with diffraction (issue 45): the defocused disc's PSF table against
the Airy pattern and Parseval, the analytic exact kernel and rendered (particle-traced) PSFs
against an independent Fresnel computation written here (the defocused pupil's FFT, each
pattern's copy moved by a Fourier phase ramp, the pixel's box as a sinc), and the limits: in
focus the Airy pattern, far out of focus the geometric disc convolved with it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.special import j1

from pacam_render.cli import main
from pacam_render.io.exr import read_exr
from pacam_render.model.camera import CameraDesign, prototype
from pacam_render.psf.analytic import design_psf, design_trajectory
from pacam_render.psf.defocused_disc import amplitude
from pacam_render.psf.diffraction import diffracted_kernel
from pacam_render.psf.exact_defocus import edge_phase, exact_defocus_kernel
from pacam_render.render.ray_defocus import MAX_LOST, defocus_table


def fresnel_otf(psi, lam_n_px, f=5, m=2048):
    """Independent reference: the OTF of |FFT of the pupil exp(i psi rho^2)|^2, the intensity
    on a grid 1/f px apart (its band, 1 / (lambda N) cycles/px, is below that grid's Nyquist),
    and its frequencies (cycles/px, FFT order)."""
    dp = 2.0 * lam_n_px * f / m
    x = (np.arange(m) - m // 2) * dp
    rr = x[:, None] ** 2 + x[None, :] ** 2
    intensity = np.abs(np.fft.fft2(np.where(rr <= 1.0, np.exp(1j * psi * rr), 0.0))) ** 2
    return np.fft.fft2(intensity / intensity.sum()), np.fft.fftfreq(m, d=1.0 / f)


def fresnel_kernel(psi, lam_n_px, points, shape, f=5, m=2048):
    """:func:`fresnel_otf`'s PSF, each point (x, y, mass) moved by a phase ramp, integrated over
    the pixel (sinc), at pixel centres."""
    otf, nu = fresnel_otf(psi, lam_n_px, f, m)
    spec = otf * np.outer(np.sinc(nu), np.sinc(nu))
    ramp = sum(w * np.exp(-2j * np.pi * (nu[:, None] * y + nu[None, :] * xk))
               for xk, y, w in points)  # fmt: skip
    full = np.fft.ifft2(spec * ramp).real
    h, w = shape
    k = full[np.ix_(((np.arange(h) - h // 2) * f) % m, ((np.arange(w) - w // 2) * f) % m)]
    return k / k.sum()


def _reference(cam, shape, origin="t0", wavelength_nm=550.0):
    segments, r = design_trajectory(cam, "coded", 0.0, origin)
    points = [(s.x0, s.y, s.w * (s.t1 - s.t0)) for s in segments]
    psi, lam_n = edge_phase(cam, r, wavelength_nm, cam.pixel_pitch_mm)
    return fresnel_kernel(psi, lam_n, points, shape), psi


def test_the_table_is_the_airy_pattern_in_focus_and_keeps_the_light():
    psis, v, pdf, _, lost = defocus_table()
    airy = 2.0 * j1(v[1:]) ** 2 / v[1:]  # (2 J1 / v)^2 v / 2
    airy /= airy.sum() * (v[1] - v[0])
    assert np.abs(pdf[0, 1:] - airy).sum() * (v[1] - v[0]) < 2e-3
    assert np.all(np.abs(lost - MAX_LOST) < 0.5 * MAX_LOST)  # the tail left out, as the Airy's
    wide = np.arange(0.0, 370.0, 0.01)  # Parseval: int |U|^2 v dv = 2 at any defocus, less
    for psi in (0.0, 3.7, 12.0):  # the tail past the table's reach (~ 2 / (pi v) of it)
        light = np.trapezoid(np.abs(amplitude(wide, psi)) ** 2 * wide, wide) / 2.0
        assert 1.0 - 3.0 * MAX_LOST < light <= 1.0 + 1e-6


@pytest.mark.parametrize("cover", [None, 1.4])
def test_the_exact_kernel_is_the_fresnel_computation(cover):
    from pacam_render.model.design import solve

    cam = prototype() if cover is None else solve(cover, base=prototype())
    shape = (41, 41)
    ref, psi = _reference(cam, shape)
    assert 0.5 < psi / (2 * np.pi) < 1.0  # 0.60 and 0.93 waves: between the two limits
    got = exact_defocus_kernel(cam, "coded", 0.0, "t0", 550.0, shape)
    assert np.abs(got - ref).sum() < 2e-3


def test_far_out_of_focus_the_exact_kernel_meets_the_geometric_one_with_airy():
    """At r = 1, 2, 3.5, 8 px the exact kernel and the geometric disc convolved with the Airy
    pattern differ less and less (the wave effect's share of the blur falls)."""
    gaps = []
    for depth in (600.0, 500.0, 400.0, 250.0):  # the prototype's focus: r = 1, 2, 3.5, 8 px
        cam = prototype().with_(object_depth_mm=depth)
        shape = (81, 81)

        def build(c, f, fine):
            return design_psf(c, "coded", 0.0, fine, origin="t0")

        airy = diffracted_kernel(build, cam, "coded", 550.0, shape)
        exact = exact_defocus_kernel(cam, "coded", 0.0, "t0", 550.0, shape)
        gaps.append((cam.r_px, np.abs(airy - exact).sum()))
    radii = [g[0] for g in gaps]
    assert radii == sorted(radii) and radii[-1] > 7.0
    l1 = [g[1] for g in gaps]
    assert all(b < a for a, b in zip(l1, l1[1:])), gaps
    assert l1[-1] < 0.85 * l1[1]  # measured: 0.25 at r = 2 px, 0.20 at 8 px


def _render(tmp_path, name, *flags):
    out = tmp_path / name
    args = ["psf", "--mode", "coded", "--velocity", "0", "--render", "--diffraction", "on",
            "--grey", "--spp", "1024", "--quiet", "--out", str(out), *flags]  # fmt: skip
    assert main(args) == 0
    meta = json.loads((out / "psf.json").read_text())
    layers = read_exr(out / "psf_rendered.exr")
    k = np.asarray(next(iter(layers.values())) if isinstance(layers, dict) else layers, float)
    k = k.squeeze()
    return k / k.sum(), CameraDesign.from_inputs(meta["camera"]), meta["origin"]


@pytest.mark.render
@pytest.mark.parametrize("flags", [("--depth", "500"), ("--depth", "500", "--cover", "1.4")])
def test_rendered_psfs_are_the_fresnel_computation(tmp_path, flags):
    """The particle tracer's exact draw: static coded PSFs at r = 2 px (the prototype) and
    r = 3.13 px (--cover 1.4), grey at 550 nm, against the independent reference."""
    k, cam, origin = _render(tmp_path, "psf", *flags)
    ref, _ = _reference(cam, k.shape, origin)
    assert np.abs(k - ref).sum() < 0.03


@pytest.mark.render
def test_in_focus_the_rendered_psf_is_the_airy_pattern(tmp_path):
    k, cam, origin = _render(tmp_path, "focus", "--depth", "751.52")  # the prototype's focus
    ref, psi = _reference(cam, k.shape, origin)
    assert psi < 0.05  # W020 < 0.01 waves
    assert np.abs(k - ref).sum() < 0.03


def _defocused_edge(r_px: float, spp: int, **kw):
    """A 5-degree edge (a dark half-plane beside it, at its depth) rendered through the
    prototype's F9.85 opening in normal mode, placed behind the focus where its blur is r px;
    (capture, lambda N px at 549 nm)."""
    from pacam_render.exposure.camera import capture_design, mode_camera
    from pacam_render.exposure.spec import CaptureSpec
    from pacam_render.wave.scale import scale_for
    from tests.edge_scenes import edge_scene, render_edge

    spec_kw = {"scene": "edge", "mode": "normal", "width": 1280, "height": 960,
               "crop": (592, 432, 96, 96), "spp": spp}  # fmt: skip
    cam = mode_camera(capture_design(CaptureSpec.geometric(**spec_kw)), "normal")[0]
    z_focus, big_r = cam.focus_distance_mm, cam.R_mm * cam.focal_length_px
    z = z_focus / (1.0 - r_px * z_focus / big_r)  # r = R f_px (z - Z_f) / (z Z_f)
    cap = render_edge(spec_kw, edge_scene(z, 5.0, dark_half=kw.pop("dark_half", True)), **kw)
    return cap, scale_for(cam, 549.0).lambda_n_px(cam.R_mm)


@pytest.mark.render
def test_a_path_traced_defocused_edge_has_the_exact_defocused_mtf():
    """Must-show (Edge): a slanted edge at r = 2 px (0.6 waves) path-traced with diffraction
    on has, in green, the MTF of the exact defocused PSF (independent Fresnel FFT, times the
    pixel's box along the edge's normal) within 0.03 from 0.05 to 0.45 cycles/px, where the
    geometric disc convolved with the Airy pattern (the rays' model before) is 0.1 away. A
    leaky LCoS keeps that model in the rays, and its edge shows it."""
    from scipy.special import j1

    from pacam_render.wave.edge_mtf import edge_mtf, fit_edge
    from pacam_render.wave.reference import circular_mtf

    r, nu = 2.0, np.linspace(0.05, 0.45, 9)
    cap, lam_n = _defocused_edge(r, 1024, diffraction="on")
    otf, grid = fresnel_otf(0.5 * np.pi * r / lam_n, lam_n)
    order = np.argsort(grid)
    tilt = np.radians(5.0)
    pixel = np.sinc(nu * np.cos(tilt)) * np.sinc(nu * np.sin(tilt))
    exact = np.interp(nu, grid[order], otf[0].real[order]) * pixel
    disc = 2.0 * j1(2.0 * np.pi * r * nu) / (2.0 * np.pi * r * nu)
    airy = np.abs(disc * circular_mtf(nu, lam_n)) * pixel
    assert np.max(np.abs(exact - airy)) > 0.1  # the two models differ here
    green = cap.image[..., 1]
    angle, offset = fit_edge(green)
    assert 4.5 < abs(angle) < 5.5
    got = edge_mtf(green, angle, offset, nu, 15.0, contrast=cap.record.light_factor)
    assert np.max(np.abs(got - exact)) < 0.03, (got, exact)
    leaky, _ = _defocused_edge(r, 1024, diffraction="on", lcos_contrast=1e6)
    old = edge_mtf(leaky.image[..., 1], angle, offset, nu, 15.0,
                   contrast=leaky.record.light_factor)  # fmt: skip
    assert np.max(np.abs(old - airy)) < 0.03 and np.max(np.abs(old - exact)) > 0.06


def test_the_occlusion_band_is_the_pixels_near_a_depth_jump():
    """A depth step (and a surface beside no surface) marks a band of the kernel's reach on
    each side; one depth, or a 0.5 % slope, marks nothing."""
    from pacam_render.exposure.optics.wave_residual import depth_jumps

    flat = np.full((20, 30), 500.0)
    assert not depth_jumps(flat, 3).any()
    assert not depth_jumps(flat * (1 + 0.0002 * np.arange(30)), 3).any()
    step = flat.copy()
    step[:, 15:] = 800.0
    band = depth_jumps(step, 3)
    assert np.array_equal(np.flatnonzero(band[7]), np.arange(11, 19))  # 14 | 15, 3 px each side
    sky = flat.copy()
    sky[:, :5] = 0.0
    assert np.array_equal(np.flatnonzero(depth_jumps(sky, 2)[0]), np.arange(2, 8))


@pytest.mark.render
def test_a_coded_capture_states_what_its_rays_diffraction_leaves_out(tmp_path):
    """Disc captures take the exact PSF in the rays: over a window at one depth nothing is
    left out (0), and on the train's edge (the train 10 mm before the wall) the record sizes
    what the rays cannot know there by its scale, the wave effect within the kernel's reach of
    the depth layer's jumps (RMS, capture units, against the sensor's noise at 10^4
    photons/px/ms). A leaky LCoS keeps the Airy draw, and the record measures that model's
    departure from the exact PSF over the whole window instead."""
    from pacam_render.capture.files import read_record

    def entry(name, crop, *extra):
        out = tmp_path / name
        args = ["render", "train", "--mode", "coded", "--crop", crop, "--spp", "16",
                "--diffraction", "on", "--sensor", "grasshopper-icx285", "--light-level",
                "10000", "--quiet", "--out", str(out), *extra]  # fmt: skip
        assert main(args) == 0
        block = read_record(out / "capture.json").optics_error
        e = block["effects"]["diffraction"]
        assert e["included"] and e["residual"]
        assert e["ratio_to_sensor"] == pytest.approx(
            e["size_rms"] / block["reference_noise"]["sigma"]
        )
        return e, block["diffraction"]["how"]

    wall, how = entry("wall", "400,500,96,64")
    assert "exact" in how and wall["size_rms"] == 0.0
    edge, _ = entry("edge", "400,560,96,96")
    assert "occluding edge" in edge["approximation"] and edge["estimate"].startswith("scale")
    assert edge["size_rms"] > 0.0
    leaky, how = entry("leaky", "400,500,96,64", "--lcos-contrast", "1e6")
    assert "Airy" in how and leaky["size_rms"] > 0.0 and leaky["estimate"].startswith("measured")
