"""Issue 56's lows and two mediums: refusals and notes that name what to change.

Item 1: a refocus beyond a store's margin advises ``--margin-px`` on the command line, and a store
rendered with the margin it names serves that refocus (the advice is checked by following it).

Item 3: ``pacam render soccer --from STORE`` of a train store said the scene's digest differs;
it names the store's scene and the command that synthesises from it.
"""

from __future__ import annotations

import re

import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import Store, synthesize

CROP = "456,410,16,12"


def _store(path, *extra) -> None:
    argv = ["lightfield", "train", "--crop", CROP, "--spp", "4", "--passes", "2", "--quiet"]
    assert main([*argv, *extra, "--out", str(path)]) == 0


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("lf") / "store"
    _store(path)
    return path


@pytest.mark.render
def test_a_refocus_beyond_the_margin_advises_the_flag_that_serves_it(store, tmp_path, capsys):
    refocus = ["render", "train", "--mode", "normal", "--depth", "300", "--quiet"]
    capsys.readouterr()
    assert main([*refocus, "--from", str(store), "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    need = re.search(r"--margin-px >= (\d+)", err)
    assert need, err
    assert not (tmp_path / "a" / "capture.exr").exists()
    wide = tmp_path / "wide"
    _store(wide, "--margin-px", need.group(1))  # the advice, followed
    assert main([*refocus, "--from", str(wide), "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "capture.exr").exists()


@pytest.mark.render
def test_another_scene_from_a_store_names_the_stores_scene(store, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "cap"
    assert main(["render", "soccer", "--from", str(store), "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "scene 'train'" in err and f"pacam render train --from {store}" in err, err
    assert not out.exists()
    lf = Store.open(store)
    spec = CaptureSpec.geometric(scene="soccer", width=1280, height=960, crop=(456, 410, 16, 12))
    with pytest.raises(ParameterError, match="is of scene 'train', not `scene` 'soccer'"):
        synthesize(lf, spec, progress=False)
