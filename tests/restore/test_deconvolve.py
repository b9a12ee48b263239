"""Deconvolution: synthetic captures (known image * known PSF + noise) against ground truth,
closed-form properties of the Wiener filter, and clear errors for bad input."""

import inspect

import numpy as np
import pytest
from scipy.signal import fftconvolve
from skimage import data

from pacam_render.errors import ParameterError
from pacam_render.psf import analytic as P
from pacam_render.restore import deconvolve as D
from pacam_render.restore import metrics

SIGMA = 0.01


def blur(x, k):
    """Linear convolution of a scene that continues past the frame (reflect), cropped."""
    pad = max(k.shape)
    xp = np.pad(x, ((pad, pad), (pad, pad)) + ((0, 0),) * (x.ndim - 2), mode="reflect")
    if x.ndim == 3:
        y = np.stack([fftconvolve(xp[..., c], k, mode="same") for c in range(x.shape[2])], -1)
    else:
        y = fftconvolve(xp, k, mode="same")
    return y[pad:-pad, pad:-pad]


@pytest.fixture(scope="module")
def capture():
    x = data.camera()[::4, ::4] / 255.0  # 128 x 128
    k = P.discrete_coded_psf(0.0, 0.04, 2.0, 22.5)
    y = blur(x, k) + np.random.default_rng(0).normal(0, SIGMA, x.shape)
    return x, k, y


# PSNR gain over the blurred input, in dB, that each method must reach
# measured: +3.9, +3.7, +3.8, +4.6 dB at 128 px; margins leave room for library versions).
MARGINS = {"wiener": 3.0, "rl": 2.5, "uwiener": 3.0, "bm3d": 3.5}


def test_default_method_is_the_cli_s_and_the_better_one(capture):
    """The API and ``pacam deconvolve`` share one default (issue 27 item 7): hl, which beats
    Wiener on a natural image at the same known noise (as bench_deconvolve measures)."""
    from pacam_render.cli import build_parser

    args = build_parser().parse_args(["deconvolve", "c.exr", "--out", "o"])
    assert inspect.signature(D.deconvolve).parameters["method"].default == args.method
    x, k, y = capture
    by_default = metrics.psnr(D.deconvolve(y, k, noise_sigma=SIGMA), x)
    assert by_default > metrics.psnr(D.deconvolve(y, k, "wiener", noise_sigma=SIGMA), x) + 0.3


@pytest.mark.parametrize("method", ["wiener", "rl", "uwiener", "bm3d"])
def test_each_method_raises_psnr(capture, method):
    x, k, y = capture
    if method == "bm3d":
        pytest.importorskip("bm3d")
    kw = {"noise_sigma": SIGMA} if method in ("wiener", "bm3d") else {}
    inp = np.clip(y, 0, None) if method == "rl" else y
    est = D.deconvolve(inp, k, method, **kw)
    assert est.shape == y.shape and np.all(np.isfinite(est))
    assert metrics.psnr(est, x) - metrics.psnr(y, x) > MARGINS[method]


def test_prior_wiener_is_close_to_oracle(capture):
    x, k, y = capture
    auto = metrics.psnr(D.wiener(y, k, noise_sigma=SIGMA), x)
    best, scale = D.oracle_wiener(y, k, x, SIGMA)
    assert metrics.psnr(best, x) >= auto - 1e-6  # the oracle can only be better
    assert metrics.psnr(best, x) - auto < 1.0  # and the documented prior is within 1 dB of it


@pytest.mark.parametrize("sigma", [0.3, 0.6])
def test_prior_wiener_stays_near_the_oracle_when_noise_swamps_the_image(sigma):
    """At very low light most frequencies are noise: the prior's level is fitted where the
    data stand above it, with a threshold that lets fewer than one noise-only frequency in.
    With 4 sigma^2 alone, the noise's 1.8 % outnumbered the signal's frequencies and the
    filter amplified noise (estimates of +-70 on a [0, 1] image, 7 dB where 15 dB is
    possible, measured on a rendered train window at 10 photons/px/ms; here 4.7 and 37 dB
    below the oracle, now 0.3 and 0.6)."""
    x = data.camera()[::2, ::2] / 255.0  # 256 x 256: many frequencies, most of them noise
    k = P.discrete_coded_psf(0.0, 0.04, 2.0, 22.5)
    y = blur(x, k) + np.random.default_rng(1).normal(0, sigma, x.shape)
    auto = D.wiener(y, k, noise_sigma=sigma)
    best, _ = D.oracle_wiener(y, k, x, sigma)
    assert np.abs(auto).max() < 3.0
    assert metrics.psnr(best, x) - metrics.psnr(auto, x) < 1.5


def test_noise_free_delta_psf_is_identity():
    x = data.camera()[::8, ::8] / 255.0
    delta = np.zeros((5, 5))
    delta[2, 2] = 1.0
    assert np.allclose(D.wiener(x, delta, nsr=0.0), x, atol=1e-10)


def test_shifted_delta_is_undone():
    """A PSF whose mass sits one pixel right of centre shifts the image; Wiener shifts it back."""
    x = data.camera()[::8, ::8] / 255.0
    k = np.zeros((3, 3))
    k[1, 2] = 1.0
    y = blur(x, k)
    assert np.allclose(y[:, 1:], x[:, :-1], atol=1e-9)  # convolution convention check
    est = D.wiener(y, k, nsr=0.0)
    assert np.abs(est - x)[4:-4, 4:-4].max() < 1e-9


def test_boundary_taper_limits_ringing():
    """With a scene that does not wrap around, tapered padding keeps the border error small."""
    x = data.camera()[::4, ::4] / 255.0
    k = P.static_psf(0.4, 22.5)  # an 18-px box: a hard PSF with spectral zeros
    y = blur(x, k)
    est = D.wiener(y, k, noise_sigma=1e-3)
    border = np.abs(est - x)
    assert border[:, :8].mean() < 3 * border[:, 40:-40].mean() + 0.02


def test_colour_matches_per_channel():
    x = data.astronaut()[::8, ::8] / 255.0
    k = P.coded_psf(0.0, 0.04, 2.0, 22.5)
    y = blur(x, k)
    rgb = D.wiener(y, k, noise_sigma=SIGMA)
    green = D.wiener(y[..., 1], k, noise_sigma=SIGMA)
    assert rgb.shape == x.shape
    assert np.allclose(rgb[..., 1], green)
    per_channel = D.wiener(y, np.stack([k] * 3, -1), noise_sigma=SIGMA)
    assert np.allclose(per_channel, rgb)


def test_faster_than_or_equal_quality_to_skimage_constant_balance(capture):
    """Same constant balance as skimage.restoration.wiener gives the same interior result."""
    from skimage.restoration import wiener as sk_wiener

    x, k, y = capture
    ours = D.wiener(y, k, nsr=1e-2)
    theirs = sk_wiener(y, k, 1e-2, reg=np.ones((1, 1)), clip=False)  # reg = identity: H*/(|H|^2+b)
    # skimage wraps around the border; compare away from it
    c = slice(30, -30)
    assert np.abs(ours[c, c] - theirs[c, c]).mean() < 0.02


@pytest.mark.parametrize(
    "psf,match",
    [
        (np.zeros((5, 5)), "all zero"),
        (np.full((5, 5), np.nan), "NaN"),
        (np.ones((300, 3)), "larger than"),
        (np.ones((5, 5, 2)), "mismatched channels"),
        (-np.ones((5, 5)), "non-negative"),
    ],
)
def test_bad_psf_errors(psf, match):
    with pytest.raises(ParameterError, match=match):
        D.wiener(np.ones((64, 64, 3)), psf)


def test_bad_image_and_method_errors():
    k = np.ones((3, 3))
    with pytest.raises(ParameterError, match="NaN"):
        D.wiener(np.full((16, 16), np.nan), k)
    with pytest.raises(ParameterError, match="unknown method"):
        D.deconvolve(np.ones((16, 16)), k, "magic")
    with pytest.raises(ParameterError, match="noise_sigma"):
        D.wiener(np.ones((16, 16)), k, noise_sigma=-1)
    with pytest.raises(ParameterError, match="non-negative image"):
        D.richardson_lucy(-np.ones((16, 16)), k)
