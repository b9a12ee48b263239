"""A capture synthesised from a light-field store says when the store's render noise is a
large share of the sensor's (issue 56: the how-to's recipe, 64 spp and a uniform proposal,
gave captures with 10x a direct render's noise and 9x the sensor's, without a word).

Reference: a store's samples are independent, so its Monte Carlo sigma goes as 1/sqrt(spp);
the spp per pass that meets 0.3x the sensor's noise is spp x (ratio / 0.3)^2.
"""

from __future__ import annotations

import math

import pytest

from pacam_render.cli import main
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.synthesis import RENDER_NOISE_SHARE, store_noise_note

pytestmark = pytest.mark.render

SPEC = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(456, 410, 24, 16),
                             spp=8, passes=2, seed=5)  # fmt: skip


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    out = tmp_path_factory.mktemp("noise") / "store"
    return render_lightfield(StoreSpec(SPEC, alpha=1.0), out, progress=False)


def test_a_noisy_store_says_so_with_the_spp_that_would_meet_the_share(store):
    cap = synthesize(store, SPEC, progress=False)
    ref = cap.record.optics_error["reference_noise"]["sigma"]
    ratio = cap.record.render_error.mc_sigma / ref
    assert ratio > RENDER_NOISE_SHARE  # 8 spp through the whole lens: far above it
    text = store_noise_note(cap)
    err = cap.record.render_error
    per_pass = err.spp // err.passes  # a store's spp is per pass: 8 here
    assert per_pass == 8
    need = math.ceil(per_pass * (ratio / RENDER_NOISE_SHARE) ** 2)
    assert f"{ratio:.2g}x the sensor's" in text and f"a store of {need} spp per pass" in text
    quiet = store_noise_note(cap, sensor_sigma=cap.record.render_error.mc_sigma / 0.2)
    assert quiet is None  # 0.2x a sensor's noise: below the share, nothing to say


def test_render_from_a_noisy_store_notes_it(store, tmp_path, capsys):
    argv = ["render", "train", "--from", str(store.folder), "--out", str(tmp_path / "c"),
            "--quiet"]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "render noise in this capture is" in err and "pacam lightfield --spp" in err
