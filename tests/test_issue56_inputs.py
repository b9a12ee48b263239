"""Issue 56, stores that cannot lie: inputs from outside refused cleanly before they cost
anything (each test fails on the main before it): a schedule nested 10^5 deep, a PNG mask or
scene texture declaring 60000x60000 px, and a render-time history that is not a bounded file."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.io.image_header import image_size
from pacam_render.model.masks import MAX_MASK_SIDE_PX, load_masks, read_mask_source
from pacam_render.model.schedule_file import read_schedule
from tests.image_bombs import bomb_png

DEPTH = 100_000  # the depth: far past Python's recursion limit (1000)


@pytest.fixture(params=["array", "object"])
def deep_schedule(tmp_path, request):
    """A schedule.json nested DEPTH levels deep: ``[[[...]]]`` or ``{"a": {"a": ...}}``."""
    path = tmp_path / "deep.json"
    if request.param == "array":
        path.write_text("[" * DEPTH + "]" * DEPTH)
    else:
        path.write_text('{"a":' * DEPTH + "1" + "}" * DEPTH)
    return path


def test_a_schedule_nested_too_deep_is_refused_naming_it(deep_schedule):
    with pytest.raises(ParameterError, match=f"`schedule` {deep_schedule} is nested too deep"):
        read_schedule(deep_schedule)


@pytest.mark.parametrize(
    "command",
    [
        ["design"],
        ["render", "train", "--width", "64", "--height", "48", "--spp", "4", "--quiet"],
        ["lightfield", "train", "--width", "64", "--height", "48", "--spp", "4", "--quiet"],
    ],
    ids=["design", "render", "lightfield"],
)
def test_a_schedule_nested_too_deep_is_one_cli_line(deep_schedule, tmp_path, capsys, command):
    out = [] if command[0] == "design" else ["--out", str(tmp_path / "out")]
    assert main([*command, "--schedule", str(deep_schedule), *out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"--schedule {deep_schedule} is nested too deep" in err
    assert not (tmp_path / "out").exists()  # refused before any work


class Decoded(BaseException):
    """Raised by a decoder the code under test must not reach (no ``except Exception`` in the
    code under test can take it for a bad file)."""


@pytest.fixture(scope="module")
def bomb(tmp_path_factory):
    """The issue's bomb: a valid PNG declaring 60000 x 60000 px (0.4 MB), written once."""
    return bomb_png(tmp_path_factory.mktemp("bomb") / "bomb.png")


@pytest.fixture
def no_decoding(monkeypatch):
    """Every image decoder the package reaches (Mitsuba's ``Bitmap``, Pillow's ``load``)
    raises :class:`Decoded`: a test with it shows that nothing was decoded."""
    import mitsuba
    from PIL import Image, ImageFile

    def decoded(*args, **kwargs):
        raise Decoded(f"decoded {args[:1]}")

    monkeypatch.setattr(mitsuba, "Bitmap", decoded)
    monkeypatch.setattr(Image.Image, "load", decoded)
    monkeypatch.setattr(ImageFile.ImageFile, "load", decoded)


def _bitmap_size(path) -> tuple[int, int]:
    import mitsuba as mi

    from pacam_render.render.backend import select_variant

    select_variant()
    return tuple(mi.Bitmap(str(path)).size())


def test_the_bomb_helper_writes_a_png_that_mitsuba_decodes(tmp_path):
    small = bomb_png(tmp_path / "small.png", side=37)
    assert _bitmap_size(small) == (37, 37) == image_size(small)
    assert load_masks(str(small)).max() == 0.0  # black: its rows are zeros


@pytest.mark.parametrize("ext", ["png", "jpg", "exr", "hdr", "pfm", "ppm", "bmp", "tga"])
def test_image_size_reads_each_format_mitsuba_reads_from_the_header(tmp_path, ext):
    """Against Mitsuba's own decoder: the size it decodes is the size the header gives."""
    import mitsuba as mi
    from PIL import Image

    from pacam_render.render.backend import select_variant

    select_variant()
    rng = np.random.default_rng(0)
    a = rng.random((5, 7, 3)).astype(np.float32)  # 7 wide, 5 tall: a swap would show
    path = tmp_path / f"a.{ext}"
    if ext in ("bmp", "tga"):  # Mitsuba reads these but does not write them
        Image.fromarray((a * 255).astype(np.uint8)).save(path)
    elif ext in ("exr", "hdr", "pfm"):
        mi.Bitmap(a).write(str(path))
    else:
        mi.Bitmap((a * 255).astype(np.uint8)).write(str(path))
    assert image_size(path) == _bitmap_size(path) == (7, 5)


def test_a_bomb_png_mask_is_refused_from_its_header(bomb, no_decoding):
    assert MAX_MASK_SIDE_PX < 60_000
    with pytest.raises(
        ParameterError, match=f"declares 60000 x 60000 px, over the {MAX_MASK_SIDE_PX}"
    ):
        load_masks(str(bomb))


def test_a_bomb_among_mask_images_is_refused_before_any_of_them_decodes(
    bomb, tmp_path, no_decoding
):
    folder = tmp_path / "lcos"
    folder.mkdir()
    bomb_png(folder / "pattern_00.png", side=16)  # read first in name order: a good mask
    (folder / "pattern_01.png").write_bytes(bomb.read_bytes())
    with pytest.raises(ParameterError, match="pattern_01.png' declares 60000 x 60000 px"):
        read_mask_source(folder)


def test_a_bomb_png_mask_is_one_cli_line(bomb, capsys, no_decoding):
    assert main(["design", "--masks", str(bomb)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"--masks: {str(bomb)!r} declares 60000 x 60000 px" in err


SCENE = """<scene version="3.0.0">
    {default}
    <shape type="rectangle" id="card">
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance">
                <string name="filename" value="{name}"/>
            </texture>
        </bsdf>
    </shape>
</scene>
"""


def _scene(folder, texture: str, through_default: bool):
    """A one-card scene whose texture is ``texture``, named as written or through a
    ``<default>`` value (``$tex``), which Mitsuba fills the same way."""
    default = f'<default name="tex" value="{texture}"/>' if through_default else ""
    path = folder / "card.xml"
    path.write_text(SCENE.format(default=default, name="$tex" if through_default else texture))
    return path


@pytest.fixture
def no_scene_load(monkeypatch):
    """Mitsuba's scene loaders raise :class:`Decoded`: a test with it shows that the scene was
    refused before Mitsuba read it (the bomb texture segfaulted the process there)."""
    import mitsuba

    def loaded(*args, **kwargs):
        raise Decoded(f"loaded {args[:1]}")

    monkeypatch.setattr(mitsuba, "load_file", loaded)
    monkeypatch.setattr(mitsuba, "load_dict", loaded)


@pytest.mark.parametrize("through_default", [False, True], ids=["written", "default"])
def test_a_bomb_texture_is_refused_before_mitsuba_loads_the_scene(
    bomb, tmp_path, no_decoding, no_scene_load, through_default
):
    from pacam_render.scenes.description import load_scene_file
    from pacam_render.scenes.scene_files import MAX_TEXTURE_SIDE_PX

    (tmp_path / "bomb.png").symlink_to(bomb)  # a link to a regular file is read through
    path = _scene(tmp_path, "bomb.png", through_default)
    over = f"declares 60000 x 60000 px, over the {MAX_TEXTURE_SIDE_PX} px"
    with pytest.raises(ParameterError, match=f"card.xml' names '.*': '.*bomb.png' {over}"):
        load_scene_file(path)


def test_a_texture_within_the_bound_still_loads(tmp_path):
    from pacam_render.scenes.description import load_scene_file

    bomb_png(tmp_path / "small.png", side=64)
    desc = load_scene_file(_scene(tmp_path, "small.png", through_default=True))
    assert "card" in desc.bboxes_mm


def test_a_bomb_texture_is_one_cli_line(bomb, tmp_path, capsys, no_scene_load):
    (tmp_path / "bomb.png").symlink_to(bomb)
    path = _scene(tmp_path, "bomb.png", through_default=False)
    args = ["render", str(path), "--width", "64", "--height", "48", "--spp", "4", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "names 'bomb.png'" in err and "declares 60000 x 60000 px" in err


def _rows(n: int) -> str:
    """``n`` history rows of known rates (0.1 s a call, 0.5 a first one, 0.02 a M samples,
    0.01 a render), as :func:`~pacam_render.exposure.render_time.remember` writes them."""
    import json

    rows = []
    for i in range(n):
        w = {"calls": 1, "first_calls": int(i == 0), "msamples": 3.0 * (i + 1),
             "renders": 10 * (i % 3 + 1)}  # fmt: skip
        s = 0.1 + 0.5 * w["first_calls"] + 0.02 * w["msamples"] + 0.01 * w["renders"]
        rows.append(json.dumps({"key": "llvm_ad_rgb", **w, "seconds": s}))
    return "\n".join(rows) + "\n"


@pytest.mark.parametrize("kind", ["fifo", "device", "link to a device", "folder"])
def test_a_history_that_is_not_a_regular_file_is_not_read(tmp_path, monkeypatch, kind):
    """/dev/zero as the history ran out of memory; a pipe waits for a writer for ever. Neither
    is read or written: the estimate keeps the reference rates and says why."""
    import os

    from pacam_render.exposure import render_time as cost

    path = {"device": "/dev/zero", "folder": str(tmp_path)}.get(kind, str(tmp_path / "times"))
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "link to a device":
        os.symlink("/dev/zero", path)
    monkeypatch.setenv("PACAM_RENDER_TIMES", path)
    cost.remember("llvm_ad_rgb", cost.Work(1, 0, 1.0, 1), 1.0)  # returns, writes nothing
    r = cost.rates("llvm_ad_rgb")
    assert r.per == cost.REFERENCE_RATES["capture"]
    est = cost.Estimate({"capture": cost.Work(1, 0, 1.0, 1)}, r).describe()
    assert f"reference machine; {path} not read: not a regular file" in est
    assert os.listdir(tmp_path) == (["times"] if path.endswith("times") else [])


def test_a_huge_history_is_read_from_its_end_only(tmp_path, monkeypatch):
    """A sparse 1 GiB history (no disk) ending in real rows: the rates come from those rows,
    and reading it (and trimming it on the next render) allocates under 4 MiB, not the file's
    size. (1 GiB, not more: were the read unbounded again, this test fails at 2 GiB.)"""
    import tracemalloc

    import scipy.optimize  # noqa: F401  (imported by the fit: not the read's memory)

    from pacam_render.exposure import render_time as cost

    path = tmp_path / "times.jsonl"
    with open(path, "wb") as f:
        f.truncate(2**30)
    junk = "[" * 2000 + "\n" + "x" * (cost.MAX_LINE_BYTES + 1) + "\n"  # too deep; too long
    with open(path, "a") as f:
        f.write("\n" + junk + _rows(cost.MIN_HISTORY + 2))
    monkeypatch.setenv("PACAM_RENDER_TIMES", str(path))
    tracemalloc.start()
    try:
        r = cost.rates("llvm_ad_rgb")
        _, read_peak = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        cost.remember("llvm_ad_rgb", cost.Work(1, 0, 1.0, 1), 0.13)  # past 96 kB: trimmed
        _, trim_peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert np.allclose(r.per, [0.1, 0.5, 0.02, 0.01], rtol=1e-6)
    assert r.basis == f"{cost.MIN_HISTORY + 2} earlier llvm_ad_rgb renders on this machine"
    assert read_peak < 4 * 2**20 and trim_peak < 4 * 2**20
    assert path.stat().st_size < 4096  # the rows and the new one are what was kept
    assert len(cost._history("llvm_ad_rgb")[0]) == cost.MIN_HISTORY + 3


@pytest.mark.parametrize(
    "kind, what",
    [("file", "a file not named .toml, .json or .exr"), ("folder", "a folder"),
     ("device", "a device, a pipe or a socket"), ("dangling link", "a link to nothing")],
)  # fmt: skip
def test_an_existing_path_that_is_not_a_design_is_not_called_a_preset(tmp_path, capsys, kind, what):
    """``--design /etc/passwd`` or a folder said "unknown preset"."""
    import os

    from pacam_render.model.design_file import resolve_design

    path = {"folder": str(tmp_path), "device": "/dev/null"}.get(kind, str(tmp_path / "passwd"))
    if kind == "file":
        with open(path, "w") as f:
            f.write("root:x:0:0:root:/root:/bin/bash\n")
    elif kind == "dangling link":
        os.symlink(tmp_path / "gone", path)
    with pytest.raises(
        ParameterError, match=f"`design` '{path}' is not a design file \\({what}\\)"
    ):
        resolve_design(path)
    assert main(["design", "--design", path]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown preset" not in err
    assert f"--design '{path}' is not a design file ({what})" in err


def test_a_preset_name_is_still_a_preset_beside_a_file_of_that_name(tmp_path, monkeypatch):
    from pacam_render.model.camera import preset
    from pacam_render.model.design_file import resolve_design

    monkeypatch.chdir(tmp_path)
    (tmp_path / "prototype").write_text("not a design\n")
    assert resolve_design("prototype") == preset("prototype")
    with pytest.raises(ParameterError, match="unknown preset 'no-such-camera'"):
        resolve_design("no-such-camera")


def test_a_motion_file_nested_too_deep_is_refused_naming_it(tmp_path, deep_schedule):
    """The scene's ``<stem>.motion.json`` was read as the schedule was: a RecursionError."""
    from pacam_render.scenes.description import load_scene_file

    bomb_png(tmp_path / "small.png", side=8)
    path = _scene(tmp_path, "small.png", through_default=False)
    (tmp_path / "card.motion.json").write_bytes(deep_schedule.read_bytes())
    with pytest.raises(ParameterError, match="motion file .*card.motion.json is nested too deep"):
        load_scene_file(path)
