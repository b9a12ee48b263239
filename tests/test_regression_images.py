"""Regression-image tests. These compare fresh renders with stored renders of our own (an
earlier output of this code, re-created by `make bless`), which is what a regression test is
for; the comparison is noise-aware (see pacam_render.experiments.regression)."""

import numpy as np
import pytest

from pacam_render.experiments import regression as R


@pytest.mark.parametrize("name", list(R.CASES))
def test_fresh_render_matches_stored_reference(name):
    seed0, seed1 = R.load_reference(name)
    verdict = R.compare(R.render_case(name, R.FRESH_SEED), seed0, seed1)
    assert verdict.ok, f"{name}: {verdict}. If the change is intended, run `make bless`."


@pytest.mark.parametrize("name", ["train_normal", "train_coded", "train_flutter", "psf_coded"])
def test_detects_one_pixel_shift_and_two_percent_brightness(name):
    seed0, seed1 = R.load_reference(name)
    fresh = R.render_case(name, R.FRESH_SEED)
    assert R.compare(fresh, seed0, seed1).ok
    assert not R.compare(np.roll(fresh, 1, axis=1), seed0, seed1).ok
    assert not R.compare(np.roll(fresh, 1, axis=0), seed0, seed1).ok
    assert not R.compare(fresh * 1.02, seed0, seed1).ok
    assert not R.compare(fresh * 0.98, seed0, seed1).ok


def test_noise_alone_passes_for_other_seeds():
    """Statistically equal renders (other seeds) pass: the test is not a bit-exact compare."""
    seed0, seed1 = R.load_reference("train_coded")
    for seed in (3, 4):
        assert R.compare(R.render_case("train_coded", seed), seed0, seed1).ok
