"""The best-shift score's search is bounded by the physics (issue 56: the prototype's box
aligned at 15 px for one seed and 0 px for another, its checker's period being about 17 px).
References: the parabola's vertex s^2 / (2 |a_i|) in closed form, and a textured object whose
restoration is its truth shifted by that much."""

import itertools
import json
from types import SimpleNamespace

import numpy as np
import pytest

from pacam_render.restore.object_score import (
    SHIFT_SLACK_PX,
    physical_shift_px,
    score,
    score_capture,
)

A_I, T, R = -0.0398, 22.5, 2.0
OPTICS = {"a_i_px_per_ms2": A_I, "T_ms": T, "r_px": R, "schedule_kind": "parabolic"}


@pytest.mark.parametrize("s", [0.0, 0.3, 0.5, 0.89, -0.7])
def test_inside_the_range_the_bound_is_the_vertex_plus_the_slack(s):
    want = int(np.ceil(s * s / (2 * abs(A_I)))) + SHIFT_SLACK_PX + int(np.ceil(R))
    assert physical_shift_px(s, "coded", OPTICS, 32) == want


def test_beyond_the_range_it_is_the_paths_reach_and_is_capped():
    """Beyond the range the restored object can sit anywhere along the relative path
    s t + a_i t^2 / 2, t in [-T, T]: its largest |x| (brute force over t)."""
    t = np.linspace(-T, T, 100_001)
    reach = np.abs(1.4 * t + A_I * t * t / 2).max()
    past = physical_shift_px(1.4, "coded", OPTICS, 99)
    assert past == int(np.ceil(reach - 1e-9)) + SHIFT_SLACK_PX + 2
    assert past > physical_shift_px(0.89, "coded", OPTICS, 99)
    assert physical_shift_px(1.4, "coded", OPTICS, 32) == 32


def test_a_still_opening_has_no_shift_and_a_designed_schedule_its_paths_reach():
    """Designed centres: |s| T + |beta| x the centres' span (the relative path's reach, brute
    force over the patterns' positions); the flutter shutter: |s| T; no exposure: no bound."""
    assert physical_shift_px(1.0, "normal", OPTICS, 32) == SHIFT_SLACK_PX + 2
    centres = [[-1.0, 0.0], [2.5, 0.0], [float("nan"), float("nan")], [0.5, 0.0]]
    design = {**OPTICS, "schedule_kind": "centres", "pattern_centres_xy_mm": centres,
              "beta_px_per_mm": -1.009}  # fmt: skip
    span = max(abs(-1.009 * (a - b)) for (a, _), (b, _) in itertools.product(
        [c for c in centres if c[0] == c[0]], repeat=2))  # fmt: skip
    want = int(np.ceil(0.5 * T + span)) + SHIFT_SLACK_PX + 2
    assert physical_shift_px(0.5, "coded", design, 99) == want
    assert physical_shift_px(0.5, "flutter", OPTICS, 99) == int(np.ceil(0.5 * T)) + 4
    assert physical_shift_px(0.5, "coded", {**design, "T_ms": None}, 32) == 32


def _capture(speed: float, est_shift: int):
    """A 40x120 window: a backdrop and a box textured with a period-17 checker moving at
    ``speed``; the restoration is the truth moved by ``est_shift`` px."""
    h, w = 40, 120
    cols = np.arange(w + 64)
    texture = 0.2 + 0.6 * ((cols // 8.5).astype(int) % 2)  # a 17 px period
    ids = np.zeros((h, w), np.int32)
    ids[8:32, 40:90] = 1
    sharp = np.full((h, w, 3), 0.5)
    sharp[8:32, 40:90] = texture[None, 40:90, None]
    est = sharp.copy()
    est[8:32, 40 + est_shift : 90 + est_shift] = texture[None, 40:90, None]
    velocity = np.zeros((h, w, 2))
    velocity[ids == 1, 0] = speed
    layers = {"sharp": sharp, "object_id": ids, "velocity": velocity}
    record = SimpleNamespace(
        objects={"0": "backdrop", "1": "box"}, optics=OPTICS, exposure_ms=2 * T, mode="coded",
        spec={"width": 1280}, camera={},
    )  # fmt: skip
    return est, layers, record


def test_a_periodic_texture_is_aligned_at_the_physical_shift_not_a_period_away():
    """The box at 0.5 px/ms moves 3.1 px (vertex); its restoration is drawn 3 + 17 = 20 px
    away, where the period matches the truth best inside the box: an unbounded search takes
    20, the bounded one stays within the physics and records the bound."""
    est, layers, record = _capture(0.5, 20)
    out = score_capture(est, layers, record)
    psnr, shift = json.loads(out["psnr_by_object"])["box"]
    bound = json.loads(out["shift_bound_px"])["box"]
    assert bound == physical_shift_px(0.5, "coded", OPTICS, 32) < 17
    assert abs(shift) <= bound
    free = score(est, layers, record.objects, {"box"}, 32)  # the search before issue 56
    assert json.loads(free["psnr_by_object"])["box"][1] == 20


def test_a_dark_pattern_of_a_bitmap_has_no_centre_in_the_span():
    """A bitmap with a black pattern: its centre is None in the record (schedule_figures), and
    the openings' span is |beta| x (largest - smallest) over the lit patterns only (it raised
    on the ragged list before)."""
    from pacam_render.restore.object_score import _opening_span_px

    optics = {"pattern_centres_xy_mm": [[1.0, 0.5], None, [3.0, -0.5]], "beta_px_per_mm": -2.0}
    assert _opening_span_px(optics) == pytest.approx(4.0)
