"""A capture's JSON is checked once, for every reader, and against its EXR (issue 37 items 7
and 10). On main before the fix, a string ``light_factor`` was a traceback in ``pacam sensor``
while ``read_capture`` accepted it; 0, -1 or NaN blamed the image; and a 64x48 EXR beside a
JSON that says 128x96 was deconvolved with a kernel for the wrong pixel size (rc 0)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from pacam_render.capture.files import read_capture
from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.io.exr import read_exr, write_exr

pytestmark = pytest.mark.render


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    out = tmp_path_factory.mktemp("cap") / "c"
    args = ["render", "train", "--width", "128", "--height", "96", "--spp", "4", "--quiet"]
    assert main([*args, "--out", str(out)]) == 0
    return out


def _copy(capture, tmp_path, **changes):
    out = tmp_path / "copy"
    shutil.copytree(capture, out)
    d = json.loads((out / "capture.json").read_text())
    d.update(changes)
    (out / "capture.json").write_text(json.dumps(d))
    return out


@pytest.mark.parametrize("bad", ["1.0", 0, -1, float("nan"), True])
def test_a_bad_light_factor_is_named_by_every_reader(capture, tmp_path, capsys, bad):
    out = _copy(capture, tmp_path, light_factor=bad)
    with pytest.raises(ParameterError, match="light_factor must be a finite number > 0"):
        read_capture(out / "capture.exr")
    capsys.readouterr()
    assert main(["sensor", str(out / "capture.exr"), "--sensor", "paper",
                 "--out", str(tmp_path / "s")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "light_factor must be a finite number > 0" in err and "Traceback" not in err
    assert main(["deconvolve", str(out / "capture.exr"), "--out", str(tmp_path / "d")]) == 2
    assert "light_factor" in capsys.readouterr().err


def test_an_exr_and_a_json_of_other_sizes_are_refused(capture, tmp_path, capsys):
    out = _copy(capture, tmp_path)
    small = {k: np.ascontiguousarray(v[::2, ::2]) for k, v in read_exr(out / "capture.exr").items()}
    write_exr(out / "capture.exr", small, force=True)
    capsys.readouterr()
    assert main(["deconvolve", str(out / "capture.exr"), "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "is 64x48 px, the JSON says 128x96" in err
    assert main(["sensor", str(out / "capture.exr"), "--sensor", "paper",
                 "--out", str(tmp_path / "s")]) == 2  # fmt: skip
    assert "disagree" in capsys.readouterr().err
    assert not (tmp_path / "d").exists() and not (tmp_path / "s").exists()


@pytest.mark.parametrize("layer, holds", [("velocity", "image velocity"), ("depth", "depth")])
def test_deconvolve_refuses_a_layer_that_is_not_an_image(capture, tmp_path, capsys, layer, holds):
    """On main: velocity blamed a --noise-sigma never given; depth was deblurred silently."""
    capsys.readouterr()
    args = ["deconvolve", str(capture / "capture.exr"), "--layer", layer]
    assert main([*args, "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert f"--layer {layer} holds {holds}" in err and "noise-sigma" not in err
    assert "deblur one of capture, sharp" in err
