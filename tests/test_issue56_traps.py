"""Issue 56's traps for a new user: answers that must say what they assume.

Trap 1: a short exposure shows one static opening, so it has no LCoS switching to blame. Its
budget sized the switching from the coded design's 16 patterns (15 switches in 45 ms), and
named it the largest left-out effect; the same figure stood with ``lcos_switching_ms`` given,
though the image did not change. Reference: a schedule that switches no pattern blends none,
so the bound (N - 1) t / E is 0 with N = 1.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec

pytestmark = pytest.mark.render

SPEC = CaptureSpec.geometric(scene="train", mode="short", width=48, height=36, spp=8, seed=1)


def test_a_short_exposure_blames_no_lcos_switching():
    short = render_capture(SPEC, progress=False, truth=False)
    budget = short.record.optics_error
    switching = budget["effects"]["lcos_switching"]
    assert switching["size_rms_per_ms"] == 0.0
    assert not switching.get("typical_matters")
    assert budget["largest_left_out"] != "lcos_switching"
    coded = render_capture(dataclasses.replace(SPEC, mode="coded"), progress=False, truth=False)
    rms = float(np.sqrt(np.mean(coded.image**2)))
    per_ms = coded.record.optics_error["effects"]["lcos_switching"]["size_rms_per_ms"]
    assert per_ms == pytest.approx(15 / 45.0 * rms)  # 16 patterns switch 15 times in 45 ms


def test_a_switching_time_asked_of_a_short_exposure_changes_nothing_and_is_sized_nil():
    plain = render_capture(SPEC, progress=False, truth=False)
    asked = render_capture(dataclasses.replace(SPEC, lcos_switching_ms=0.1), progress=False,
                           truth=False)  # fmt: skip
    assert np.array_equal(plain.image, asked.image)
    switching = asked.record.optics_error["effects"]["lcos_switching"]
    assert not switching["included"] and switching["size_rms"] == 0.0
    assert asked.record.optics_error["largest_left_out"] != "lcos_switching"
