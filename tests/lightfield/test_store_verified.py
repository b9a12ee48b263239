"""A light-field store is verified when read (issue 56, items 1-4): every shard, the truth
layers and the manifest are the ones the store wrote, or the read is refused in one line that
names the file. Each tampering below gave a capture with exit 0, or a traceback, before.

References: the store's own digests (``store.json`` records each shard's, the truth's and its
own when the store is finished); a forgery that recomputes them is caught by the content
checks (finite, non-negative radiance; the arrays and the step a render writes).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import Store, StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.store import (
    load_shard,
    manifest_digest,
    save_shard,
    store_digest,
)
from pacam_render.scenes import load_scene

pytestmark = pytest.mark.render

FULL = {"scene": "train", "width": 1280, "height": 960}
SPEC = CaptureSpec.geometric(**FULL, crop=(456, 410, 16, 12), spp=4, passes=2, seed=3)


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """A store of the window, and one of another window of the same size (same steps)."""
    root = tmp_path_factory.mktemp("verified")
    a = render_lightfield(StoreSpec(SPEC), root / "a", progress=False)
    other = dataclasses.replace(SPEC, crop=(200, 560, 16, 12))
    b = render_lightfield(StoreSpec(other), root / "b", progress=False)
    return a.folder, b.folder


def _copy(folder: Path, tmp_path: Path) -> Path:
    out = tmp_path / "store"
    shutil.copytree(folder, out)
    return out


def _read(folder: Path):
    """Open the store and synthesise its own capture (every shard and the truth read)."""
    return synthesize(Store.open(folder), SPEC, progress=False)


def _refused(folder: Path, names: str) -> str:
    with pytest.raises(ParameterError) as info:
        _read(folder)
    text = str(info.value)
    assert "\n" not in text and names in text and "allow_pickle" not in text, text
    return text


def _manifest(folder: Path) -> dict:
    return json.loads((folder / "store.json").read_text())


def _write_manifest(folder: Path, m: dict, resign: bool) -> None:
    """Write ``m``; with ``resign``, as a forger would: its digests made to agree again."""
    if resign:
        m["digest"] = store_digest(m["key"], m["shard_digests"])
        m["manifest_digest"] = manifest_digest(m)
    (folder / "store.json").write_text(json.dumps(m))


def _forge(folder: Path, name: str, change) -> None:
    """Rewrite one shard with ``change(records, meta)`` applied, and re-sign the manifest so
    that only the content checks can catch it."""
    records, meta = load_shard(folder / name)
    change(records, meta)
    digest = save_shard(folder, name, records, meta)
    m = _manifest(folder)
    p, k = int(name[1:3]), int(name[5:9])
    m["shard_digests"][p][k] = digest
    _write_manifest(folder, m, resign=True)


def test_an_untouched_store_reads(stores):
    cap = _read(stores[0])
    assert np.isfinite(cap.image).all() and (cap.image >= 0).all()


def test_a_shard_of_another_window_or_pass_is_refused(stores, tmp_path):
    a = _copy(stores[0], tmp_path)
    shutil.copy(stores[1] / "p00_s0000.npz", a / "p00_s0000.npz")  # another window's
    assert "store.json recorded" in _refused(a, "p00_s0000.npz")
    a = _copy(stores[0], tmp_path / "dup")
    shutil.copy(a / "p00_s0000.npz", a / "p01_s0000.npz")  # a duplicated pass
    assert "store.json recorded" in _refused(a, "p01_s0000.npz")


@pytest.mark.parametrize(
    "field,value",
    [
        (("camera", "window"), [456, 410, 16, 13]),
        (("spec", "capture", "crop"), [460, 410, 16, 12]),
        (("camera", "margin_px"), 40),
        (("channels",), 1),
        (("digest",), "0123456789abcdef"),
        (("camera", "exposure_ms"), 0),
    ],
)
def test_an_edited_manifest_is_refused(stores, tmp_path, field, value):
    a = _copy(stores[0], tmp_path)
    m = _manifest(a)
    node = m
    for k in field[:-1]:
        node = node[k]
    node[field[-1]] = value
    _write_manifest(a, m, resign=False)
    assert "the manifest was edited" in _refused(a, "store.json")


def test_a_manifest_edited_and_resigned_is_checked_against_itself(stores, tmp_path):
    """A forger who recomputes the digests still meets the manifest's own checks."""
    for field, value, says in (("camera", {"window": [456, 410, 16, 13]}, "window"),
                               ("channels", 1, "channels")):  # fmt: skip
        a = _copy(stores[0], tmp_path / says)
        m = _manifest(a)
        m[field] = {**m[field], **value} if isinstance(value, dict) else value
        _write_manifest(a, m, resign=True)
        assert says in _refused(a, "store.json")


@pytest.mark.parametrize(
    "text",
    ["{}", '{"format": "pacam-lightfield/1", "complete": true}', "[" * 100000 + "]" * 100000],
)
def test_a_broken_manifest_is_refused_in_one_line(stores, tmp_path, text):
    a = _copy(stores[0], tmp_path)
    (a / "store.json").write_text(text)
    with pytest.raises(ParameterError) as info:
        Store.open(a)
    assert "\n" not in str(info.value) and "store.json" in str(info.value)


def test_a_manifest_without_its_spec_is_refused(stores, tmp_path):
    a = _copy(stores[0], tmp_path)
    m = _manifest(a)
    del m["spec"]
    _write_manifest(a, m, resign=True)
    assert "not a readable store manifest" in _refused(a, "store.json")


@pytest.mark.parametrize("how", ["truncated", "empty", "fifo", "zero", "passwd"])
@pytest.mark.parametrize("name", ["p00_s0000.npz", "truth.npz"])
def test_a_damaged_file_is_refused_in_one_line(stores, tmp_path, how, name):
    a = _copy(stores[0], tmp_path)
    path = a / name
    if how == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
    elif how == "empty":
        path.write_bytes(b"")
    else:
        path.unlink()
        if how == "fifo":
            os.mkfifo(path)
        else:
            path.symlink_to("/dev/zero" if how == "zero" else "/etc/passwd")
    why = "not a regular file" if how in ("fifo", "zero") else "not a readable light-field shard"
    assert why in _refused(a, name)


@pytest.mark.parametrize(
    "change,says",
    [
        (lambda r, m: r["L"].__setitem__((0, 0), -5.0), "negative"),
        (lambda r, m: r["L"].__setitem__((0, 0), np.inf), "not finite"),
        (lambda r, m: r.pop("u"), "lacks u"),
        (lambda r, m: r.__setitem__("x", r["x"].astype(np.float64)), "float32"),
        (lambda r, m: r.__setitem__("L", r["L"][:1]), "channels"),
        (lambda r, m: m.__setitem__("spp", 0), "spp"),
    ],
)
def test_a_forged_shard_is_refused_by_its_content(stores, tmp_path, change, says):
    a = _copy(stores[0], tmp_path)
    _forge(a, "p00_s0000.npz", change)
    text = _refused(a, "p00_s0000.npz")
    assert says in text


def test_the_motion_file_is_part_of_the_scene_digest(stores, tmp_path):
    """A store of a scene whose motion changed since serves no capture (it served the old
    motion before)."""
    desc = load_scene("train")
    moved = dataclasses.replace(desc, motions={})  # the same description, no motion
    assert moved.digest() == desc.digest() and moved.motion_digest() != desc.motion_digest()
    with pytest.raises(ParameterError, match="digest differs"):
        synthesize(Store.open(stores[0]), SPEC, progress=False, description=moved)


def test_render_from_a_damaged_store_exits_with_one_line(stores, tmp_path, capsys):
    a = _copy(stores[0], tmp_path)
    (a / "p00_s0000.npz").write_bytes(b"PK\x03\x04 not a zip")
    code = main(["render", "train", "--from", str(a), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and "p00_s0000.npz" in err[0], err
