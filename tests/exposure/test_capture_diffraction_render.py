"""Diffraction in the rays, through whole captures (issue 36's must-shows).

References, all independent of the sampler under test: the circular pupil's
diffraction-limited MTF (closed form, :func:`~pacam_render.wave.reference.circular_mtf`), the
Airy pattern integrated over each pixel by Gauss-Legendre quadrature
(:func:`~pacam_render.wave.reference.airy_kernel_quadrature`), and a uniform emitter, which
any jitter of the film position leaves exactly as it is.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.camera import capture_design, mode_camera
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.wave.edge_mtf import edge_mtf, fit_edge
from pacam_render.wave.reference import airy_kernel_quadrature, circular_mtf
from pacam_render.wave.scale import scale_for
from tests.edge_scenes import edge_scene, render_edge

pytestmark = pytest.mark.render

FULL = {"width": 1280, "height": 960}


def _lambda_n(spec: CaptureSpec, wavelength_nm: float) -> float:
    cam, _ = mode_camera(capture_design(spec), spec.mode)
    return scale_for(cam, wavelength_nm).lambda_n_px(cam.R_mm)


def test_an_in_focus_edge_takes_the_circular_pupils_mtf():
    """Normal mode at F9.85, the edge at the focus distance: MTF(on) / MTF(off) in green is the
    circular pupil's diffraction-limited MTF within 0.03 from 0.05 to 0.45 cycles/px."""
    kw = {"scene": "edge", "mode": "normal", **FULL, "crop": (592, 432, 96, 96), "spp": 2048}
    spec = CaptureSpec.geometric(**kw)
    desc = edge_scene(mode_camera(capture_design(spec), "normal")[0].focus_distance_mm, 5.0)
    off = render_edge(kw, desc, diffraction="off")
    on = render_edge(kw, desc, diffraction="on")
    angle, offset = fit_edge(off.image[..., 1])
    assert 4.0 < abs(angle) < 6.0  # the tilted edge, seen
    nu = np.linspace(0.05, 0.45, 9)
    lf = off.record.light_factor
    ratio = edge_mtf(on.image[..., 1], angle, offset, nu, 15.0, contrast=lf) / edge_mtf(
        off.image[..., 1], angle, offset, nu, 15.0, contrast=lf
    )
    want = circular_mtf(nu, _lambda_n(spec, 549.0))
    assert np.max(np.abs(ratio - want)) < 0.03, (ratio, want)
    assert np.max(np.abs(1.0 - want)) > 0.3  # diffraction is far from nothing here
    block = on.record.optics_error
    assert (
        block["effects"]["diffraction"]["included"] and "in the rays" in block["diffraction"]["how"]
    )


def _point_scene(cam, n: int, diffraction: bool, as_dict: bool = False):
    """An in-focus point on the axis, a window film of n x n pixels (n odd: the point images
    at the centre of the middle pixel) at the camera's pixel scale, ``ptracer``."""
    import mitsuba as mi

    z, f = cam.focus_distance_mm, cam.focal_length_px
    sensor = {
        "type": "programmable_aperture",
        "fov": 2 * np.degrees(np.arctan(0.5 * n / f)),
        "lens_radius": cam.R_max_mm,
        "aperture_radius": cam.R_mm,
        "focus_distance": z,
        "film": {"type": "hdrfilm", "width": n, "height": n, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent"},
    }
    if diffraction:
        sensor.update(
            diffraction_wavelengths="611, 549, 464",
            pupil_distance=2 * cam.F_min * cam.R_max_mm,
            pixel_pitch=cam.pixel_pitch_mm,
        )
    rs = 0.02 * z / f  # 0.02 px
    disk = {
        "type": "disk",
        "to_world": mi.ScalarTransform4f(
            np.array([[-rs, 0, 0, 0], [0, rs, 0, 0], [0, 0, -1.0, z], [0, 0, 0, 1.0]])
        ),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1 / (np.pi * 0.02**2)}},
    }
    integ = {"type": "ptracer", "max_depth": 2}
    scene = {"type": "scene", "sensor": sensor, "disk": disk, "integrator": integ}
    return scene if as_dict else mi.load_dict(scene)


_POINT_RENDERS = """
import sys
import numpy as np
import mitsuba as mi
from pacam_render.model.camera import prototype
from pacam_render.model.modes import capture_camera
from pacam_render.render.backend import select_variant
from tests.exposure.test_capture_diffraction_render import _point_scene

select_variant(mono=False)
cam = capture_camera(prototype(), "normal")
n = 33
geometric = _point_scene(cam, n, False)  # 64 spp as 16 renders of 4, summed in float64: its
# one lit pixel takes every splat, and 64 spp of them in float32 came out 0.07 % apart from
# run to run (the threads' order), which moved the red chi^2 from 1.17 to 4.24
off = sum(np.array(mi.render(geometric, spp=4, seed=k), float) for k in range(16)) / 16
scene = _point_scene(cam, n, True)
on = np.array([np.array(mi.render(scene, spp=64, seed=k), float) for k in range(128)])
np.savez(sys.argv[1], off=off, on=on)
"""


@pytest.fixture(scope="module")
def point(tmp_path_factory):
    """The point through the F9.85 disc, without and with diffraction: 128 renders of 64 spp
    each, summed in float64 (one render of many more spp loses light to float32 splats).

    Rendered in a process of its own. The geometric render's one lit pixel sums its splats in
    float32 in the threads' order: rendered at 64 spp at once, its total came out 0.0808067 or
    0.0807486 from run to run (half the runs under load), and the red channel's chi^2, which
    divides by it, 4.24 instead of 1.17. It is now 16 renders of 4 spp summed in float64."""
    import subprocess
    import sys
    from pathlib import Path

    from pacam_render.model.camera import prototype
    from pacam_render.model.modes import capture_camera

    root = Path(__file__).resolve().parents[2]
    out = tmp_path_factory.mktemp("point") / "point.npz"
    done = subprocess.run([sys.executable, "-c", _POINT_RENDERS, str(out)], cwd=root,
                          capture_output=True, text=True, timeout=900)  # fmt: skip
    assert done.returncode == 0, done.stderr
    with np.load(out) as z:
        off, on = z["off"], z["on"]
    return capture_camera(prototype(), "normal"), 33, off, on


def test_an_in_focus_point_is_the_pixel_integrated_airy_pattern_of_each_channel(point):
    """Each colour channel against the Airy pattern at its own wavelength, integrated over the
    pixels, at the Monte Carlo floor: the pooled chi^2 per pixel is at most 1.6 (it is ~1).
    Another channel's wavelength, or no diffraction, is many sigma away."""
    cam, n, off, on = point
    total = off.sum(axis=(0, 1))  # all the light: the geometric point is one pixel
    assert off[n // 2, n // 2, 1] == pytest.approx(total[1], rel=1e-6)
    waves = (611.0, 549.0, 464.0)
    refs = [airy_kernel_quadrature(scale_for(cam, w).lambda_n_px(cam.R_mm), n) for w in waves]
    for c in range(3):
        runs = on[..., c] / total[c]
        got, var = runs.mean(axis=0), float(np.mean(runs.var(axis=0, ddof=1))) / len(runs)
        chi2 = [float(np.mean((got - ref / 0.998) ** 2)) / var for ref in refs]  # 0.998: v_max
        assert chi2[c] < 1.6, (waves[c], chi2)
        assert min(chi2[k] for k in range(3) if k != c) > 20.0, (waves[c], chi2)
        geometric = off[..., c] / total[c]
        assert np.mean((geometric - refs[c]) ** 2) / var > 1000.0


def test_a_uniform_emitter_stays_uniform_even_through_one_lcos_pixel(tmp_path):
    """Stiff case: an opening of one LCoS pixel in radius (Airy first zero ~150 px) on a uniform
    emitter: every jitter sees the same radiance, so the image is the light factor times it,
    finite everywhere, within its Monte Carlo error."""
    from pacam_render.model.design_file import write_design
    from tests.exposure.test_render_error import _glowing_wall

    kw = {"scene": "wall", "mode": "normal", **FULL, "crop": (600, 440, 24, 16), "spp": 64}
    one = capture_design(CaptureSpec.geometric(**kw)).with_(R_mm=0.01362)  # the smallest opening
    write_design(tmp_path / "one.toml", one)
    cap = render_edge(kw, _glowing_wall(False), diffraction="on", design=str(tmp_path / "one.toml"))
    assert 120 < 1.22 * cap.record.optics_error["diffraction"]["lambda_n_px"][1] < 200
    assert np.isfinite(cap.image).all()
    lf = cap.record.light_factor
    sigma = cap.mc_sigma.mean()
    assert abs(float(cap.image.mean()) - 0.8 * lf) < 5 * sigma / np.sqrt(cap.image.size)


def test_a_closed_disc_is_refused_with_the_parameter_named():
    from pacam_render.render.ray_diffraction import RayDiffractionSpec

    rays = RayDiffractionSpec("549", 39.0, 0.00645)
    with pytest.raises(ParameterError, match="aperture_radius > 0"):
        rays.lambda_n_px(0.0)
    one = rays.lambda_n_px(0.01362)[0]
    assert 120 < 1.22 * one < 200  # the one-LCoS-pixel opening's first zero, px


def test_cli_render_reports_diffraction_and_the_budget(tmp_path, capsys):
    out = tmp_path / "c"
    code = main(
        ["render", "train", "--mode", "coded", "--width", "48", "--height", "36", "--spp", "8",
         "--diffraction", "on", "--sensor", "grasshopper-icx285", "--no-truth",
         "--out", str(out), "--quiet"]
    )  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "diffraction on, as asked; in the rays (exact defocused PSF) at 611/549/464 nm" in text
    assert "optics left out: largest is" in text
    rec = json.loads((out / "capture.json").read_text())
    effects = rec["optics_error"]["effects"]
    assert sorted(effects) == sorted([
        "diffraction", "relative_illumination", "lcos_leakage", "lcos_grid",
        "lcos_switching", "bounces",
    ])  # fmt: skip
    assert rec["optics_error"]["reference_noise"]["sensor"].startswith("grasshopper-icx285")
    assert rec["spec"]["diffraction"] == "on"


def test_auto_includes_diffraction_for_the_coded_prototype_at_the_crossovers_target():
    """The crossover study's target (0.2 x the ICX285's noise at 10^4 photons/px/ms) on part
    of its window: the preview measures diffraction above it, so ``auto`` includes it."""
    from pacam_render.sensor.apply import SensorTarget

    spec = CaptureSpec(
        scene="train", mode="coded", **FULL, crop=(360, 600, 96, 64), diffraction="auto"
    )
    target = SensorTarget(0.2, (("grasshopper-icx285", 1e4),))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = render_capture(spec, progress=False, truth=False, target=target, pilot_only=True)
    info = cap.record.optics_error["diffraction"]
    assert info["decision"].startswith("auto: included"), info["decision"]
    assert cap.record.optics_error["effects"]["diffraction"]["included"]


def test_psf_like_and_deconvolve_follow_the_captures_diffraction(tmp_path, capsys):
    """psf --like gives the kernel the capture's diffraction: in focus, the Airy pattern
    (checked against the pixel-integrated Airy pattern by quadrature, over the kernel's window,
    which holds all but the far rings' last 1 %); deconvolve refuses a kernel without it, and
    one whose rays' PSF (exact or geometric x Airy) is not the capture's."""
    from pacam_render.capture.files import read_record
    from pacam_render.capture.kernels import analytic_psf
    from pacam_render.psf.diffraction import convolve_kernels

    cap = tmp_path / "cap"
    common = ["--width", "1280", "--height", "960", "--crop", "600,440,48,32", "--spp", "8"]
    assert main(["render", "train", "--mode", "normal", *common, "--diffraction", "on",
                 "--out", str(cap), "--quiet"]) == 0  # fmt: skip
    rec = read_record(cap / "capture.exr")
    geometric = analytic_psf(type(rec)(**{**rec.__dict__, "optics_error": None}))
    info = rec.optics_error["diffraction"]
    airy = airy_kernel_quadrature(info["lambda_n_px"][1], 151)
    want = convolve_kernels(geometric, airy / airy.sum())
    got = analytic_psf(rec)
    n = min(got.shape[0], want.shape[0]) // 2
    c_got, c_want = got.shape[0] // 2, want.shape[0] // 2
    crop = np.s_[c_got - n : c_got + n + 1, c_got - n : c_got + n + 1]
    crop_w = np.s_[c_want - n : c_want + n + 1, c_want - n : c_want + n + 1]
    held = want[crop_w].sum()
    assert 0.99 <= held < 1.0 and got.shape[0] < want.shape[0]  # DECONVOLUTION_MAX_LOST
    assert np.abs(got[crop] - want[crop_w] / held).sum() < 5e-3
    assert main(["psf", "--like", str(cap / "capture.exr"), "--velocity", "0",
                 "--out", str(tmp_path / "p")]) == 0  # fmt: skip
    meta = json.loads((tmp_path / "p" / "psf.json").read_text())
    assert meta["diffraction"] == {"wavelength_nm": 549.0, "pixel_pitch_mm": 0.00645,
                                   "psf": "exact"}  # fmt: skip
    older = tmp_path / "p" / "psf.json"  # a kernel of the rays before: geometric x Airy
    meta["diffraction"].pop("psf")
    older.write_text(json.dumps(meta))
    kernel = str(tmp_path / "p" / "psf_analytic.exr")
    code = main(["deconvolve", str(cap / "capture.exr"), "--psf", kernel,
                 "--out", str(tmp_path / "o")])  # fmt: skip
    assert code == 2
    assert "fraunhofer defocused PSF (PSF) against exact (capture)" in capsys.readouterr().err
    assert main(["psf", "--like", str(cap / "capture.exr"), "--velocity", "0",
                 "--diffraction", "off", "--out", str(tmp_path / "q")]) == 0  # fmt: skip
    kernel = str(tmp_path / "q" / "psf_analytic.exr")
    code = main(["deconvolve", str(cap / "capture.exr"), "--psf", kernel,
                 "--out", str(tmp_path / "d")])  # fmt: skip
    assert code == 2
    assert "no diffraction (PSF) against diffraction included (capture)" in capsys.readouterr().err


def _grid_point(fill: float | None, n: int = 601):
    """An in-focus point through the F9.85 disc with diffraction and the LCoS grid of linear
    fill factor ``fill``, on an n x n window film (ptracer, 8 renders of 4 spp)."""
    import mitsuba as mi

    from pacam_render.model.camera import prototype
    from pacam_render.model.modes import capture_camera
    from pacam_render.render.backend import select_variant

    select_variant(mono=False)
    cam = capture_camera(prototype(), "normal")
    scene_dict = _point_scene(cam, n, True, as_dict=True)
    if fill is not None:
        scene_dict["sensor"]["lcos_fill_factor"] = fill
    scene = mi.load_dict(scene_dict)
    return cam, sum(np.array(mi.render(scene, spp=4, seed=k), float) for k in range(8)) / 8


def test_the_lcos_grid_puts_its_orders_where_and_as_bright_as_the_grating_says():
    """Fill factor 0.8: the first order (1, 0) of each channel lies at lambda D / pitch px
    (271.6, 244.0, 206.3 px) within 0.3 px, and holds sinc^2(0.8) = 0.0547 of the zero
    order's light within 4 %; fill factor 1 has no orders and is the render without a grid.
    (The film holds orders |m| <= 1: the renders' light is (0.811 + 2 x 0.044)^2 of the
    zero-order-only light times f^2.)"""
    from pacam_render.render.ray_diffraction import order_px

    cam, img = _grid_point(0.8)
    c0, half = img.shape[0] // 2, 15
    ys, xs = np.mgrid[-half : half + 1, -half : half + 1]
    for ch, wl in enumerate((611.0, 549.0, 464.0)):
        d = order_px(wl, 2 * cam.F_min * cam.R_max_mm, 0.01362, cam.pixel_pitch_mm)
        zero = img[c0 - half : c0 + half + 1, c0 - half : c0 + half + 1, ch].sum()
        k = int(round(d))
        box = img[c0 - half : c0 + half + 1, c0 + k - half : c0 + k + half + 1, ch]
        assert (box * xs).sum() / box.sum() + k == pytest.approx(d, abs=0.3)
        assert box.sum() / zero == pytest.approx(np.sinc(0.8) ** 2, rel=0.04)
    _, ideal = _grid_point(1.0)
    _, none = _grid_point(None)
    k = int(round(order_px(549.0, 2 * cam.F_min * cam.R_max_mm, 0.01362, cam.pixel_pitch_mm)))
    assert ideal[c0 - half : c0 + half + 1, c0 + k - half : c0 + k + half + 1].sum() == 0.0
    # the same draws (ptracer's float32 splats add in a thread-dependent order)
    assert np.allclose(ideal, none, rtol=1e-4, atol=1e-9)


def test_fill_factor_needs_diffraction_and_is_checked():
    with pytest.raises(ParameterError, match="lcos_fill_factor: the grid's orders are diffraction"):
        CaptureSpec.geometric(lcos_fill_factor=0.9)
    with pytest.raises(ParameterError, match=r"lcos_fill_factor must be in \(0, 1\]"):
        CaptureSpec(lcos_fill_factor=1.5, diffraction="on")
    assert (
        CaptureSpec(lcos_fill_factor=0.9, diffraction="on").key() != CaptureSpec.geometric().key()
    )
