"""A study of the camera with its optics (issue 36): ``[render] relative_illumination`` and
``diffraction``. A point flat-fields the sensor's image and the noise it tells the deconvolver,
as ``pacam deconvolve`` does, before it restores and scores against the radiance truth."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.restore.capture_score import flat_sigma as _flat_sigma
from pacam_render.restore.capture_score import radiance
from pacam_render.study.point import Task, capture_inputs, run_task
from pacam_render.study.report import diffraction_cell
from pacam_render.study.spec import parse_study

TINY = {
    "study": {"name": "tiny-optics"},
    "render": {"width": 32, "height": 24, "spp": 8, "noise_ratio": False, "max_step_px": 4.0},
    "grid": {"mode": ["normal"], "light_level": [3000.0], "method": ["hl"]},
}


def _with(**render) -> dict:
    return {**TINY, "render": {**TINY["render"], **render}}


def test_the_optics_keys_enter_the_study_key_only_when_on():
    plain = parse_study(TINY)
    assert parse_study(_with(relative_illumination="off", diffraction="off")).key() == plain.key()
    cos4 = parse_study(_with(relative_illumination="cos4"))
    auto = parse_study(_with(diffraction="auto"))
    assert len({plain.key(), cos4.key(), auto.key()}) == 3
    spec, _, _ = capture_inputs(cos4.render, cos4.points[0])
    assert spec.relative_illumination == "cos4" and spec.diffraction == "off"
    spec, _, _ = capture_inputs(plain.render, plain.points[0])
    assert spec.relative_illumination == "off"


@pytest.mark.parametrize(
    "render, match",
    [
        ({"relative_illumination": "cos5"}, r"\[render\] relative_illumination must be off, cos4"),
        ({"diffraction": "maybe"}, r"\[render\] diffraction must be one of auto, on, off"),
    ],
)
def test_bad_optics_values_are_refused_naming_the_key(render, match):
    with pytest.raises(ParameterError, match=match):
        parse_study(_with(**render))


def test_radiance_and_sigma_divide_by_the_map():
    """Closed forms: layer / light_factor / m, and sigma sqrt(mean(m^-2))."""
    m = np.full((4, 6), 0.5, dtype="float32")
    m[:, :3] = 1.0
    layer = np.full((4, 6, 3), 0.2)
    cap = SimpleNamespace(
        extra_layers={"relative_illumination": m}, record=SimpleNamespace(light_factor=0.1)
    )
    assert np.allclose(radiance(cap, layer), 2.0 / m[..., None])
    assert _flat_sigma(cap, 0.01) == pytest.approx(0.01 * np.sqrt((1 + 4) / 2))
    cap.extra_layers = {}
    assert np.allclose(radiance(cap, layer), 2.0) and _flat_sigma(cap, 0.01) == 0.01


@pytest.mark.render
def test_a_point_with_cos4_is_flat_fielded_before_it_is_scored():
    """The whole frame of a binned sensor (cos^4 = 0.61 at its corners): rendered with cos4,
    the noise the point reports is the flat-fielded one, larger than the radiance capture's
    (the irradiance image's own noise is smaller: fewer photons), and the scores stay close."""
    rows = {}
    for ri in ("off", "cos4"):
        spec = parse_study(_with(relative_illumination=ri))
        (rows[ri],) = run_task(Task(spec.render, spec.points))
        assert rows[ri]["status"] == "ok", rows[ri]["status"]
    off, cos4 = rows["off"], rows["cos4"]
    assert cos4["noise_sigma"] > off["noise_sigma"]  # divided by m < 1 towards the corners
    assert abs(cos4["psnr_db"] - off["psnr_db"]) < 1.0
    assert np.isfinite(cos4["model_sigma"]) and cos4["model_sigma"] < 0.05


def test_the_plateau_tables_diffraction_cell():
    assert diffraction_cell([{"diffraction": "in"}] * 3) == "in"
    out = [{"diffraction": "out", "diffraction_sigma": v} for v in (0.001, 0.003, "")]
    assert diffraction_cell(out) == "out 0.002"
    assert diffraction_cell([{"diffraction": "in"}, {"diffraction": "out"}]) == "mixed"
    assert diffraction_cell([{"diffraction": ""}, {}]) == ""  # rows before the optics columns
