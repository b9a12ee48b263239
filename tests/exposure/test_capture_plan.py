"""A capture resolves its camera once (issue 48): the plan every stage reads, counted against
the design's reader, and the plan's figures against independent paths to them."""

import numpy as np
import pytest

import pacam_render.model.design_file as design_file
from pacam_render.exposure.camera import capture_design, mode_camera
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model import camera
from pacam_render.model.camera import prototype
from pacam_render.model.design_file import write_design

TINY = {"scene": "train", "width": 24, "height": 18, "spp": 4}


def _counting(monkeypatch, owner, name):
    calls = []
    real = owner[name] if isinstance(owner, dict) else getattr(owner, name)

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    if isinstance(owner, dict):
        monkeypatch.setitem(owner, name, counted)
    else:
        monkeypatch.setattr(owner, name, counted)
    return calls


@pytest.mark.render
def test_a_capture_reads_its_design_file_once(tmp_path, monkeypatch):
    """With diffraction ``auto`` (a preview render, then the capture), the relative illumination
    (the capture's pixel pitch) and the resume key, the design file is read once."""
    path = tmp_path / "mine.toml"
    write_design(path, prototype().with_(R_mm=2.5, name="mine"))
    reads = _counting(monkeypatch, design_file, "read_design")
    spec = CaptureSpec(**TINY, design=str(path), diffraction="auto", relative_illumination="cos4")
    cap = render_capture(spec, partial_dir=tmp_path / "out" / ".partial", progress=False)
    assert len(reads) == 1
    assert cap.record.design["R_mm"] == 2.5
    assert "preview" in cap.record.optics_error["diffraction"]["decision"]  # auto did render one


@pytest.mark.render
def test_a_capture_builds_its_preset_once(monkeypatch):
    builds = _counting(monkeypatch, camera.PRESETS, "prototype")
    render_capture(CaptureSpec(**TINY, diffraction="auto", relative_illumination="cos4"),
                   progress=False)  # fmt: skip
    assert len(builds) == 1


def test_the_plan_agrees_with_the_spec_resolved_the_long_way():
    """Each figure of the plan equals the one the capture's helpers give from the spec alone."""
    spec = CaptureSpec(
        mode="normal",
        cover_px_per_ms=1.2,
        object_depth_mm=600.0,
        relative_illumination="cos4",
        lcos_contrast=200.0,
        width=64,
        height=48,
    )
    plan = plan_capture(spec)
    design = capture_design(spec)
    cam, params = mode_camera(design, "normal")
    assert plan.design == design and plan.cam == cam and plan.mode_params == params
    assert plan.pitch_mm == pytest.approx(0.00645 * 1280 / 64)  # 64 px across 1280 of 6.45 um
    assert plan.key() == spec.key()
    sensor = plan.with_diffraction(False, "off").sensor_params()
    assert sensor["lcos_contrast"] == 200.0 and sensor["relative_illumination"] == "cos4"
    assert list(sensor)[: len(params)] == list(params)  # the mode's parameters first
    assert any("cover_px_per_ms has no effect" in n for n in plan.notes)


def test_a_design_files_key_is_its_digest(tmp_path):
    path = tmp_path / "d.toml"
    write_design(path, prototype().with_(R_mm=2.5))
    spec = CaptureSpec.geometric(**TINY, design=str(path), object_depth_mm=700.0)
    plan = plan_capture(spec)
    assert plan.key() == spec.key()  # the digest of the file as read, not of the depth's
    assert plan.full.object_depth_mm == 700.0


@pytest.mark.render
def test_a_plan_renders_as_its_spec():
    spec = CaptureSpec(**TINY, mode="coded", diffraction="on")
    a = render_capture(spec, progress=False, truth=False)
    b = render_capture(plan_capture(spec), progress=False, truth=False)
    assert np.array_equal(a.image, b.image)
    assert a.record.notes == b.record.notes and a.record.sensor_params == b.record.sensor_params


def test_the_optics_defaults_have_one_owner():
    """The spec's module owns both sets: ``CaptureSpec``'s fields, and ``CAMERA_OPTICS``,
    which ``pacam render``, ``validate-scene`` and the demo take."""
    from pacam_render.cli import build_parser
    from pacam_render.experiments.validate_scene import SceneCheck
    from pacam_render.exposure.spec import CAMERA_OPTICS, GEOMETRIC_OPTICS

    spec = CaptureSpec.geometric()
    assert {k: getattr(spec, k) for k in GEOMETRIC_OPTICS} == GEOMETRIC_OPTICS
    args = build_parser().parse_args(["render", "train", "--out", "x"])
    assert {k: getattr(args, k) for k in CAMERA_OPTICS} == CAMERA_OPTICS
    check = SceneCheck(scene="train")
    assert {k: getattr(check, k) for k in CAMERA_OPTICS} == CAMERA_OPTICS
