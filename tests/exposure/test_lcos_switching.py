"""The LCoS's switching time in the rays (issue 36, item 3).

Reference: the closed form of a linear change. Two disc patterns, each shown for half of the
45 ms exposure (D = 22.5 ms); in the first t of the second window the display still shows
the first pattern with probability 1 - tau / t, so the first pattern is seen for D + t/2 and
the second for D - t/2. A defocused point's image is then the mix of the two patterns' images
(each rendered alone, as one static disc) with those weights, and its centroid is theirs.
"""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.spec import CaptureSpec

pytestmark = pytest.mark.render

N = 61


def _scene(centres: str, t_ms: float | None = None):
    import mitsuba as mi

    from pacam_render.render.backend import select_variant

    select_variant(mono=False)
    sensor = {
        "type": "programmable_aperture", "fov": 10.0, "lens_radius": 5.0,
        "aperture_radius": 1.0, "focus_distance": 500.0, "schedule": "centres",
        "centres": centres, "shutter_open": 0.0, "shutter_close": 45.0,
        "film": {"type": "hdrfilm", "width": N, "height": 9, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent"},
    }  # fmt: skip
    if t_ms is not None:
        sensor["lcos_switching"] = t_ms
    rs = 0.05  # a small disc emitter at 400 mm: defocused, so each opening shifts its image
    disk = {
        "type": "disk",
        "to_world": mi.ScalarTransform4f(
            np.array([[-rs, 0, 0, 0], [0, rs, 0, 0], [0, 0, -1.0, 400.0], [0, 0, 0, 1.0]])
        ),
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 100.0}},
    }
    integ = {"type": "ptracer", "max_depth": 2}
    return mi.load_dict({"type": "scene", "sensor": sensor, "disk": disk, "integrator": integ})


def _centroid(scene) -> tuple[float, float]:
    import mitsuba as mi

    img = sum(np.array(mi.render(scene, spp=128, seed=k), float)[..., 1] for k in range(4))
    return float((img.sum(axis=0) * np.arange(N)).sum() / img.sum()), float(img.sum())


@pytest.mark.parametrize("t_ms", [5.0, 22.5])
def test_a_switching_display_mixes_neighbouring_patterns_as_a_linear_change_does(t_ms):
    u0, light = _centroid(_scene("-3 0"))
    u1, _ = _centroid(_scene("3 0"))
    assert u1 - u0 > 1.0  # the two openings image the point a pixel apart
    got, got_light = _centroid(_scene("-3 0; 3 0", t_ms))
    want = ((22.5 + t_ms / 2) * u0 + (22.5 - t_ms / 2) * u1) / 45.0
    assert got == pytest.approx(want, abs=0.005)
    assert got_light == pytest.approx(light, rel=2e-3)  # the same light, only moved
    instant, _ = _centroid(_scene("-3 0; 3 0"))
    assert abs(instant - got) > 8 * 0.005  # and visibly not the instant display


def test_switching_is_checked_and_named():
    bad = (ParameterError, RuntimeError)  # Mitsuba's loader wraps the plugin's error
    with pytest.raises(bad, match="lcos_switching .30 ms. must be at most a pattern's time"):
        _scene("-3 0; 3 0", 30.0)
    with pytest.raises(ParameterError, match="lcos_switching_ms must be >= 0"):
        CaptureSpec.geometric(lcos_switching_ms=-1.0)
    import mitsuba as mi

    film = {"type": "hdrfilm", "width": 8, "height": 8}
    static = {"type": "programmable_aperture", "lens_radius": 5.0, "lcos_switching": 1.0}
    with pytest.raises(bad, match="lcos_switching: the static schedule has no discs"):
        mi.load_dict({**static, "film": film})
