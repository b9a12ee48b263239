"""Issue 26, items 1, 2 and 5: a resume keys on every input's contents, and a checkpoint is
checked before it is trusted. Each test failed on the main of 2026-11-23."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pacam_render.exposure.direct import CaptureInterrupted, render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.limits import PacamWarning
from pacam_render.study.spec import parse_study
from tests.patching import patch_everywhere

WALL = """<scene version='3.0.0'>
    <shape type='rectangle' id='wall'>
        <transform name='to_world'><scale value='400'/><translate z='1500'/></transform>
        {extra}
        <bsdf type='diffuse'><texture type='checkerboard' name='reflectance'>
            <transform name='to_uv'><scale value='8'/></transform></texture></bsdf>
    </shape>
    <shape type='sphere' id='ball'>
        <point name='center' x='0' y='0' z='500'/><float name='radius' value='40'/>
    </shape>
    <emitter type='constant'/>
</scene>"""


def _xml(folder, extra: str = ""):
    xml = folder / "m.xml"
    xml.write_text(WALL.format(extra=extra))
    motion = {"shapes": {"ball": {"velocity_mm_per_ms": [-0.3, 0.0, 0.0]}}}
    (folder / "m.motion.json").write_text(json.dumps(motion))
    return xml


@pytest.mark.render
def test_an_xml_attribute_that_traverse_misses_starts_afresh(tmp_path):
    """flip_normals is not among mi.traverse's parameters: the scene's own text is keyed."""
    xml = _xml(tmp_path)
    spec = CaptureSpec.geometric(scene=str(xml), mode="coded", width=32, height=24, spp=16)
    part = tmp_path / "out" / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=6, truth=False)
    _xml(tmp_path, "<boolean name='flip_normals' value='true'/>")
    with pytest.warns(PacamWarning, match=r"\(scene changed\)"):
        resumed = render_capture(spec, partial_dir=part, progress=False, truth=False)
    fresh = render_capture(spec, progress=False, truth=False)
    assert np.array_equal(resumed.image, fresh.image)


def _schedule(path, centre_mm: float):
    doc = {
        "centres_mm": [[x, 0.0] for x in np.linspace(-centre_mm, centre_mm, 16)],
        "radius_mm": 1.0,
        "focus_distance_mm": 750.0,
        "n_patterns": 16,
    }
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.render
def test_a_schedule_rewritten_in_place_starts_afresh(tmp_path):
    sched = _schedule(tmp_path / "schedule.json", 3.0)
    spec = CaptureSpec.geometric(
        scene="train", mode="coded", width=40, height=30, spp=8, schedule=str(sched)
    )
    part = tmp_path / "out" / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=5, truth=False)
    _schedule(sched, 4.0)  # same path, other contents
    with pytest.warns(PacamWarning, match=r"\(spec changed\)"):
        resumed = render_capture(spec, partial_dir=part, progress=False, truth=False)
    fresh = render_capture(spec, progress=False, truth=False)
    assert np.array_equal(resumed.image, fresh.image)


def test_a_study_keys_on_the_contents_of_the_files_it_names(tmp_path):
    sched = _schedule(tmp_path / "schedule.json", 3.0)
    doc = {"grid": {"mode": ["coded"], "design": [f"schedule={sched}"]}}
    before = parse_study(doc).key()
    assert parse_study(doc).key() == before
    _schedule(sched, 4.0)
    assert parse_study(doc).key() != before


@pytest.mark.render
@pytest.mark.parametrize("steps_done", [999, -3, "x"])
def test_a_tampered_checkpoint_is_never_trusted(tmp_path, steps_done):
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=32, height=24, spp=8, seed=1)
    part = tmp_path / "out" / ".partial"
    with pytest.raises(CaptureInterrupted):
        render_capture(spec, partial_dir=part, progress=False, stop_after_steps=4, truth=False)
    saved = json.loads((part / "state.json").read_text())
    saved["state"]["steps_done"] = steps_done
    (part / "state.json").write_text(json.dumps(saved))
    with pytest.warns(PacamWarning, match=r"starting afresh"):
        cap = render_capture(spec, partial_dir=part, progress=False, truth=False)
    assert cap.record.resumed_from_step == 0
    assert np.array_equal(cap.image, render_capture(spec, progress=False, truth=False).image)


# --- 6. a failed write keeps the render ----------------------------------------------------------
@pytest.mark.render
def test_a_full_disk_at_the_exr_write_keeps_the_render(tmp_path, capsys, monkeypatch):
    import errno

    import pacam_render.io.exr as exr
    from pacam_render.cli import main

    out = tmp_path / "c"
    argv = ["render", "train", "--width", "40", "--height", "30", "--spp", "8", "--quiet"]
    argv += ["--out", str(out)]
    real = exr.write_exr

    def full_disk(path, *args, **kwargs):
        if str(path).startswith(str(out)):
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, *args, **kwargs)

    patch_everywhere(monkeypatch, exr, "write_exr", full_disk)
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "No space left on device" in err and "Traceback" not in err
    assert f"kept in {out / '.partial'}" in err and "written to" in err
    rescue = Path(err.split("written to ")[1].split(":")[0])
    assert (rescue / "capture.exr").is_file()
    patch_everywhere(monkeypatch, exr, "write_exr", real)
    assert main(argv) == 0  # resumes from the kept passes: nothing is rendered again
    meta = json.loads((out / "capture.json").read_text())
    assert meta["resumed_from_step"] == meta["n_steps"] * meta["render_error"]["passes"]
    assert not (out / ".partial").exists()


@pytest.mark.render
def test_a_checkpoint_that_cannot_be_saved_does_not_stop_the_capture(tmp_path, monkeypatch):
    import errno

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("pacam_render.exposure.checkpoint.atomic_save", full)
    spec = CaptureSpec.geometric(scene="train", mode="coded", width=32, height=24, spp=8)
    with pytest.warns(PacamWarning, match="could not save the finished work"):
        cap = render_capture(
            spec, partial_dir=tmp_path / "c" / ".partial", progress=False, save_every_s=0
        )
    assert np.array_equal(cap.image, render_capture(spec, progress=False).image)
