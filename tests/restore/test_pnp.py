"""Plug-and-play deconvolution (pnp): quality against the known sharp image, the stiff cases
of issue 29 (zero, constant, saturated, sigma near 0 and very large, NaN, an image smaller than
the network's receptive field) and the error when scico is missing."""

import sys

import numpy as np
import pytest
from scipy.signal import fftconvolve
from skimage import color, data, transform

from pacam_render import prototype
from pacam_render.errors import ParameterError
from pacam_render.psf.analytic import design_psf
from pacam_render.restore import pnp
from pacam_render.restore.deconvolve import METHODS, deconvolve
from pacam_render.restore.metrics import psnr

try:
    import scico  # noqa: F401

    HAVE_SCICO = True
except ImportError:
    HAVE_SCICO = False
needs_scico = pytest.mark.skipif(not HAVE_SCICO, reason="pip install 'pacam_render[pnp]'")
BOX = np.ones((3, 3))


def _blur(x, k):
    pad = k.shape[0]
    return fftconvolve(np.pad(x, pad, mode="reflect"), k / k.sum(), mode="same")[pad:-pad, pad:-pad]


def _photo(size: int):
    return transform.resize(color.rgb2gray(data.astronaut()), (size, size), anti_aliasing=True)


def test_pnp_is_a_method():
    assert "pnp" in METHODS


def test_missing_scico_names_the_method_and_the_install(monkeypatch):
    pnp._network.cache_clear()
    monkeypatch.setitem(sys.modules, "scico.denoiser", None)  # import fails as if absent
    with pytest.raises(ParameterError, match=r"'pnp'.*pip install 'pacam_render\[pnp\]'"):
        deconvolve(np.ones((16, 16)), BOX, "pnp", noise_sigma=0.01)
    pnp._network.cache_clear()


@needs_scico
def test_pnp_beats_wiener_on_a_photograph():
    """192 px astronaut, prototype's coded kernel, sigma 0.01: measured pnp 27.17 dB, Wiener
    25.86 dB (bench_pnp.py has the 256 px figures)."""
    k = design_psf(prototype(), "coded", 0.0)
    x = _photo(192)
    y = _blur(x, k) + np.random.default_rng(0).normal(0, 0.01, x.shape)
    wiener = psnr(deconvolve(y, k, "wiener", noise_sigma=0.01), x)
    assert psnr(deconvolve(y, k, "pnp", noise_sigma=0.01), x) > wiener + 1.0


@needs_scico
def test_pnp_zero_constant_and_per_channel():
    for shape in ((24, 24), (24, 24, 3)):
        assert np.array_equal(deconvolve(np.zeros(shape), BOX, "pnp"), np.zeros(shape))
    # the residual's local mean is put back, so a flat image comes back exactly (the
    # network alone biased it by 0.8 to 1.8 %)
    for sigma in (0.01, None):
        flat = deconvolve(np.full((24, 24), 0.3), BOX, "pnp", noise_sigma=sigma)
        assert np.allclose(flat, 0.3, rtol=1e-9)
    grey = _blur(_photo(32), BOX)
    one = deconvolve(grey, BOX, "pnp", noise_sigma=0.01)
    three = deconvolve(np.stack([grey] * 3, axis=-1), BOX, "pnp", noise_sigma=0.01)
    assert np.allclose(three, one[..., None], atol=1e-6)


@needs_scico
def test_pnp_is_scale_free():
    x = _photo(32)
    y = _blur(x, BOX) + np.random.default_rng(1).normal(0, 0.01, x.shape)
    a = deconvolve(y, BOX, "pnp", noise_sigma=0.01)
    b = deconvolve(0.07 * y, BOX, "pnp", noise_sigma=0.0007)  # a capture's units
    assert np.allclose(b, 0.07 * a, rtol=1e-4, atol=1e-6)


@needs_scico
def test_pnp_on_a_saturated_image():
    """A capture clipped at 1 over a quarter of the frame: finite, and the clipped plateau
    stays at its level."""
    x = np.clip(2.0 * _photo(64), 0.0, 1.0)
    y = _blur(x, BOX)
    assert (y >= 1.0 - 1e-9).mean() > 0.2
    out = deconvolve(y, BOX, "pnp", noise_sigma=0.01)
    assert np.isfinite(out).all()
    plateau = y >= 1.0 - 1e-9
    assert abs(np.median(out[plateau]) - 1.0) < 0.02
    assert psnr(out, x) > psnr(y, x)


@needs_scico
@pytest.mark.parametrize("sigma", [0.0, 1e-12, 1e-4])
def test_pnp_with_sigma_near_zero(sigma):
    """Noiseless input: the schedule ends at SIGMA_MIN, not at 0 (an inverse filter). Measured
    at 0: pnp 26.78 dB, Wiener 25.16, blurred 23.79."""
    x = _photo(64)
    y = _blur(x, BOX)
    out = deconvolve(y, BOX, "pnp", noise_sigma=sigma)
    wiener = psnr(deconvolve(y, BOX, "wiener", noise_sigma=sigma), x)
    assert np.isfinite(out).all() and psnr(out, x) > max(wiener + 0.5, psnr(y, x) + 2.0)


@needs_scico
def test_pnp_with_a_very_large_sigma():
    """sigma 0.5 on a [0, 1] image, past the network's training (0.2): it is asked for 0.2.
    Measured 16.7 dB against the input's 5.9."""
    x = _photo(64)
    y = _blur(x, BOX) + np.random.default_rng(2).normal(0, 0.5, x.shape)
    out = deconvolve(y, BOX, "pnp", noise_sigma=0.5)
    assert np.isfinite(out).all() and psnr(out, x) > psnr(y, x) + 6.0


@needs_scico
@pytest.mark.parametrize("sigma", [1.0, 2.4])
def test_pnp_with_noise_past_the_signal(sigma):
    """A short exposure in the dark: noise past the image's own range (a delta kernel).
    The image is scaled so the noise stays within the network's training; measured
    +14.9 dB and +17.0 dB over the input (without that scaling +13.5 and +15.5)."""
    x = _photo(128)
    y = x + np.random.default_rng(0).normal(0, sigma, x.shape)
    out = deconvolve(y, np.ones((1, 1)), "pnp", noise_sigma=sigma)
    assert np.isfinite(out).all() and psnr(out, x) > psnr(y, x) + 14.0


@needs_scico
def test_pnp_on_an_image_smaller_than_the_receptive_field():
    """10 x 10 px against 6 layers of 3 x 3 filters (13 px): a flat image stays flat, a noisy
    ramp comes back within 3 sigma (measured RMS error 0.025)."""
    flat = deconvolve(np.full((10, 10), 0.3), BOX, "pnp", noise_sigma=0.01)
    assert np.allclose(flat, 0.3, rtol=1e-9)
    yy, xx = np.mgrid[0:10, 0:10] / 10.0
    x = 0.2 + 0.5 * xx + 0.2 * yy
    y = _blur(x, BOX) + np.random.default_rng(3).normal(0, 0.01, x.shape)
    out = deconvolve(y, BOX, "pnp", noise_sigma=0.01)
    assert out.shape == x.shape and np.sqrt(np.mean((out - x) ** 2)) < 0.03


def _turns(planes, k):
    """The k-th of the 8 flips and quarter turns, written out by hand."""
    p = planes[..., ::-1] if k % 2 else planes
    return np.rot90(p, k // 2, axes=(1, 2))


@pytest.mark.parametrize("n", pnp.ENSEMBLES)
def test_self_ensemble_against_brute_force(n):
    """A denoiser that does not commute with the turns (a one-pixel shift plus a ramp, on a
    non-square image): the mean of the inverse-turned outputs, computed here by hand; one that
    commutes (a symmetric 3x3 mean with wrap-around) gives its own output."""
    planes = np.random.default_rng(4).random((2, 6, 9))

    def shift(p, level):
        return np.roll(p, 1, axis=2) + level * np.arange(p.shape[2])

    want = np.zeros_like(planes)
    for k in range(n):
        out = np.rot90(shift(_turns(planes, k).copy(), 0.1), -(k // 2), axes=(1, 2))
        want += out[..., ::-1] if k % 2 else out
    assert np.allclose(pnp.self_ensemble(shift, planes, 0.1, n), want / n)

    def box(p, level):
        from scipy.ndimage import uniform_filter

        return uniform_filter(p, size=(1, 3, 3), mode="wrap")

    assert np.allclose(pnp.self_ensemble(box, planes, 0.1, n), box(planes, 0.1))


def test_schedule_ends_at_end_factor_times_sigma():
    levels = pnp.schedule(0.01, 5)
    assert np.isclose(levels[0], pnp.SIGMA_START) and np.isclose(levels[-1], pnp.END_FACTOR * 0.01)
    assert np.allclose(np.diff(np.log(levels)), np.log(levels[1] / levels[0]))  # geometric
    # never raised past the network's training, nor below sigma: then constant
    assert np.allclose(pnp.schedule(0.1, 3), pnp.SIGMA_TRAINED)
    assert np.allclose(pnp.schedule(0.3, 3), 0.3)


def test_pnp_refuses_bad_input_before_any_work():
    y = np.ones((16, 16))
    with pytest.raises(ParameterError, match="NaN"):
        deconvolve(np.where(np.eye(16) > 0, np.nan, y), BOX, "pnp", noise_sigma=0.01)
    with pytest.raises(ParameterError, match="noise_sigma"):
        deconvolve(y, BOX, "pnp", noise_sigma=-1.0)
    with pytest.raises(ParameterError, match="iterations"):
        deconvolve(y, BOX, "pnp", iterations=0)
    with pytest.raises(ParameterError, match="lam"):
        deconvolve(y, BOX, "pnp", lam=0.0)
    for bad in (3, 0, True, 2.5):
        with pytest.raises(ParameterError, match=r"ensemble must be one of \(1, 2, 4, 8\)"):
            deconvolve(y, BOX, "pnp", ensemble=bad)


@pytest.mark.parametrize(("method", "module"), [("pnp", "scico"), ("bm3d", "bm3d")])
def test_a_missing_optional_package_is_refused_before_any_work(
    monkeypatch, tmp_path, capsys, method, module
):
    """Study files and ``pacam deconvolve`` check the method's package up front: a study naming
    pnp without scico fails at load, not after its renders; the CLI before reading the capture
    (which here does not even exist)."""
    import importlib.util

    from pacam_render.cli import main
    from pacam_render.restore.deconvolve import require_method
    from pacam_render.study import load_study

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == module else real(name, *a)
    )
    with pytest.raises(ParameterError, match=rf"'{method}'.*pip install"):
        require_method(method)
    require_method("hl")  # no optional package: passes
    spec = tmp_path / "s.toml"
    spec.write_text(f'[study]\nname = "s"\n[grid]\nmode = ["coded"]\nmethod = ["{method}"]\n')
    with pytest.raises(ParameterError, match=rf"point .*'{method}'.*pip install"):
        load_study(str(spec))
    argv = ["deconvolve", str(tmp_path / "none.exr"), "--method", method]
    assert main([*argv, "--out", str(tmp_path / "o")]) == 2
    assert "pip install" in capsys.readouterr().err
