"""A tiny dataset rendered serially (2 scenes x 2 cameras, 32x24 windows, 4 spp): its index,
its sample folders read back by the loader and by the EXR reader alike, resuming without a
render, a failed sample recorded and retried, the same spec giving the same digests, and a
family's scene cards in the data card."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pacam_render.dataset import open_dataset, parse_spec, run_dataset
from pacam_render.dataset import sample as sample_module
from pacam_render.dataset.card import occlusion_share
from pacam_render.dataset.index import read_index
from pacam_render.dataset.plan import plan_dataset
from pacam_render.errors import ParameterError
from pacam_render.exposure.direct import render_capture
from pacam_render.io.exr import read_exr, write_exr
from tests.patching import patch_everywhere

pytestmark = pytest.mark.render

ROOT = Path(__file__).resolve().parents[2]
MY_SCENE = ROOT / "docs" / "howto" / "my_scene.xml"
CAPTURE = {"width": 1280, "height": 960, "crop": [440, 420, 32, 24], "spp": 4,
           "diffraction": "off"}  # fmt: skip
SENSOR = {"preset": "grasshopper-icx285", "light_levels": [300]}


def _spec(scenes, cameras=("coded", "normal"), **top):
    cams = [{"name": m, "mode": m} for m in cameras]
    doc = {"name": "tiny", "seed": 1, "scenes": scenes, "capture": dict(CAPTURE),
           "cameras": cams, "sensor": dict(SENSOR), **top}  # fmt: skip
    return parse_spec(doc)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "tiny"
    spec = _spec(["train", str(MY_SCENE)])
    summary = run_dataset(spec, out, workers=0, progress=False)
    return spec, out, summary


def test_tiny_dataset_index_and_folders(tiny):
    spec, out, summary = tiny
    rows = read_index(out)
    assert (summary.rendered, summary.failed, summary.skipped) == (4, 0, 0)
    assert [r["status"] for r in rows] == ["ok"] * 4
    assert {r["camera"] for r in rows} == {"coded", "normal"}
    for r in rows:
        assert float(r["render_error"]) > 0 and float(r["seconds"]) > 0
        held = {p.name for p in (out / "samples" / r["id"]).iterdir()}
        assert {"capture.exr", "capture.json", "psf_analytic.exr", "psf.json"} <= held
    assert (out / "card.md").is_file() and (out / "card" / "render_error.png").is_file()
    assert not list((out / "samples").glob(".*"))  # no temporary folder left


def test_loader_returns_the_files_arrays(tiny):
    _, out, _ = tiny
    ds = open_dataset(out)
    assert len(ds) == 4 and len(list(ds)) == 4
    s = ds[0]
    layers = read_exr(out / "samples" / s.id / "capture.exr")
    shapes = {"capture": (24, 32, 3), "noisy": (24, 32, 3), "raw": (24, 32),
              "sharp": (24, 32, 3), "depth": (24, 32), "velocity": (24, 32, 2),
              "object_id": (24, 32)}  # fmt: skip
    for name, shape in shapes.items():
        got = getattr(s, name)
        assert got.shape == shape, name
        np.testing.assert_array_equal(got, layers[name])
    psf = read_exr(out / "samples" / s.id / "psf_analytic.exr")["psf"]
    np.testing.assert_array_equal(s.psf, psf)
    assert s.psf.ndim == 2 and s.psf.sum() == pytest.approx(1.0, rel=1e-3)
    assert s.record["sample"]["key"] == s.row["key"] and s.record["mode"] == s.row["camera"]
    assert s.record["sensor"]["light_level_photons_per_px_per_ms"] == 300


def test_an_edited_sample_or_index_is_refused_in_one_line(tiny, tmp_path):
    """A sample's arrays are checked against the digest sample.json recorded when it was
    written (one changed pixel of capture.exr is refused, naming the folder); an index that is
    not a dataset's is refused naming it."""
    _, out, _ = tiny
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    sid = open_dataset(copy)[0].id
    exr = copy / "samples" / sid / "capture.exr"
    layers = read_exr(exr)
    layers["noisy"][0, 0, 0] += 0.5
    write_exr(exr, layers, force=True)
    with pytest.raises(ParameterError, match=f"{sid}: its arrays' digest"):
        open_dataset(copy)[0]
    assert open_dataset(copy)[1].id != sid  # the others still read
    (copy / "index.csv").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ParameterError, match="index.csv"):
        open_dataset(copy)


def _no_render(*args, **kwargs):
    raise AssertionError("a finished sample was rendered again")


def test_resume_renders_nothing(tiny, monkeypatch):
    spec, out, _ = tiny
    before = (out / "index.csv").read_text()
    patch_everywhere(monkeypatch, sample_module, "render_capture", _no_render)
    again = run_dataset(spec, out, workers=0, progress=False)
    assert (again.rendered, again.skipped, again.failed) == (0, 4, 0)
    assert (out / "index.csv").read_text() == before


def test_another_spec_is_refused_without_force(tiny):
    _, out, _ = tiny
    with pytest.raises(ParameterError, match="another spec"):
        run_dataset(_spec(["train"], seed=2), out, workers=0, progress=False)


def test_failed_sample_is_recorded_then_retried(tiny, tmp_path, monkeypatch):
    _, first, _ = tiny
    spec, out = _spec(["train"], cameras=("coded",)), tmp_path / "one"

    def boom(*args, **kwargs):
        raise RuntimeError("boom")

    with monkeypatch.context() as m:
        patch_everywhere(m, sample_module, "render_capture", boom)
        failed = run_dataset(spec, out, workers=0, progress=False)
    (row,) = read_index(out)
    assert failed.failed == 1 and row["status"] == "failed" and "boom" in row["error"]
    assert len(open_dataset(out)) == 0 and len(open_dataset(out, status=None)) == 1
    retried = run_dataset(spec, out, workers=0, progress=False)
    (row,) = read_index(out)
    assert retried.rendered == 1 and row["status"] == "ok"
    # the same spec's sample, rendered in another dataset: the same key and arrays
    same = {r["id"]: r for r in read_index(first)}[row["id"]]
    assert (row["key"], row["digest"]) == (same["key"], same["digest"])


def test_family_scenes_and_their_cards(tmp_path):
    """Two seeds of the real ``occluders`` family (issue 57 item 1) through the pinhole: the
    scenes are generated into the dataset, and the data card's occlusion share is the one
    the scene cards' events give (counted here from scene.json)."""
    capture = {**CAPTURE, "crop": [600, 440, 24, 16]}
    spec = _spec({"family": "occluders", "seeds": 2}, cameras=("reference",), capture=capture)
    summary = run_dataset(spec, tmp_path / "fam", workers=0, progress=False)
    rows = read_index(tmp_path / "fam")
    assert summary.rendered == 2 and [r["scene_seed"] for r in rows] == ["0", "1"]
    assert all(r["scene"].startswith("family:occluders:") for r in rows)
    cards = [json.loads(p.read_text()) for p in sorted((tmp_path / "fam").rglob("scene.json"))]
    assert len(cards) == 2 and all(c["occlusion_events"] for c in cards)
    for c in cards:
        hit = {e[k] for e in c["occlusion_events"] for k in ("front", "behind")}
        want = sum(o["id"] in hit for o in c["objects"]) / len(c["objects"])
        assert occlusion_share(c) == want > 0
    card = (tmp_path / "fam" / "card.md").read_text()
    for name in ("depth", "speed", "occlusion_share", "render_error"):
        assert f"card/{name}.png" in card
    assert open_dataset(tmp_path / "fam")[0].psf is None  # a reference capture has no PSF


def test_a_store_per_scene_serves_its_cameras(tmp_path):
    """``store = "always"``: one light-field store of the scene gives the coded and normal
    captures (their records cite it), the pinhole is rendered directly, the store is removed
    once its samples are written, and the synthesised coded capture agrees with a direct
    render of the same camera within the two captures' stated sigmas (pooled chi^2)."""
    capture = {**CAPTURE, "spp": 16, "passes": 4}
    spec = _spec(["train"], cameras=("coded", "normal", "reference"), capture=capture,
                 run={"store": "always"})  # fmt: skip
    summary = run_dataset(spec, tmp_path / "st", workers=0, progress=False)
    assert (summary.rendered, summary.failed) == (3, 0)
    assert not (tmp_path / "st" / ".stores").exists() or not any(
        (tmp_path / "st" / ".stores").iterdir()
    )
    data = {s.row["camera"]: s for s in open_dataset(tmp_path / "st")}
    assert "lightfield" in data["coded"].record and "lightfield" in data["normal"].record
    assert "lightfield" not in data["reference"].record
    direct = render_capture(replace(spec_capture(spec, "coded"), seed=99), progress=False)
    a, sa = data["coded"].capture, data["coded"].record["render_error"]["mc_sigma"]
    chi2 = np.mean((a - direct.image) ** 2) / (sa**2 + direct.record.render_error.mc_sigma**2)
    assert 0.6 < chi2 < 1.6, chi2


def spec_capture(spec, camera: str):
    """The CaptureSpec the dataset renders ``camera`` of its first scene with."""
    return next(r.spec for r in plan_dataset(spec).renders if r.camera == camera)


def test_a_switching_lcos_camera_is_synthesised_from_the_store(tmp_path):
    """A camera whose LCoS switches (``lcos_switching_ms``, the blend stores draw as the plugin
    does) is served by the scene's store, and agrees with a direct render of the same camera
    within the two captures' sigmas (pooled chi^2); its record keeps the switching time."""
    cams = [{"name": "coded", "mode": "coded"},
            {"name": "sw", "mode": "coded", "lcos_switching_ms": 2.0}]  # fmt: skip
    doc = {"name": "sw", "seed": 1, "scenes": ["train"], "sensor": dict(SENSOR),
           "capture": {**CAPTURE, "spp": 16, "passes": 4}, "cameras": cams,
           "run": {"store": "always"}}  # fmt: skip
    spec = parse_spec(doc)
    via = {r.camera: r.via for r in plan_dataset(spec).renders}
    assert via == {"coded": "store", "sw": "store"}
    assert run_dataset(spec, tmp_path / "sw", workers=0, progress=False).failed == 0
    data = {s.row["camera"]: s for s in open_dataset(tmp_path / "sw")}
    assert "lightfield" in data["sw"].record
    assert data["sw"].record["sensor_params"]["lcos_switching"] == 2.0
    direct = render_capture(replace(spec_capture(spec, "sw"), seed=99), progress=False)
    a, sa = data["sw"].capture, data["sw"].record["render_error"]["mc_sigma"]
    chi2 = np.mean((a - direct.image) ** 2) / (sa**2 + direct.record.render_error.mc_sigma**2)
    assert 0.6 < chi2 < 1.6, chi2
