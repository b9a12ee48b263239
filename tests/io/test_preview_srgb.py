"""The previews' sRGB encoding against colour-science's (an independent implementation)."""

import colour
import numpy as np

from pacam_render.io.preview import srgb8, srgb_encode


def test_srgb_encode_matches_colour_science():
    x = np.concatenate([np.linspace(0.0, 0.01, 2001), np.linspace(0.01, 1.0, 5001)])
    ref = colour.cctf_encoding(x, function="sRGB")
    assert np.max(np.abs(srgb_encode(x) - ref)) < 1e-12


def test_srgb8_is_colour_sciences_encoding_rounded():
    rng = np.random.default_rng(3)
    img = rng.uniform(0.0, 2.0, (17, 23, 3))
    exposure = 0.8
    ref = np.round(colour.cctf_encoding(np.clip(img * exposure, 0, 1), function="sRGB") * 255)
    assert np.array_equal(srgb8(img, exposure), ref.astype(np.uint8))
