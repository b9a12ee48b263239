"""A dataset's spec and plan, without rendering: every bad key is named with its valid range,
the plan counts scenes x cameras x light levels with stable keys, the disk bound is refused
before any work, and the CLI answers a bad spec with one line and exit 2."""

from __future__ import annotations

import math

import pytest

from pacam_render.cli import main
from pacam_render.dataset import break_even_cameras, parse_spec, plan_dataset
from pacam_render.dataset.plan import SIDECAR_BYTES, STORE_RATIOS, store_ratio, use_store
from pacam_render.errors import FileKeyError, ParameterError
from pacam_render.io.toml_file import parse_toml

BASE = """
name = "t"
seed = 3
scenes = ["train", "walker"]
[capture]
width = 1280
height = 960
crop = [440, 420, 32, 24]
spp = 4
diffraction = "off"
[[cameras]]
name = "ref"
mode = "reference"
[[cameras]]
name = "ref2"
mode = "reference"
depth_mm = 700
[[cameras]]
name = "coded"
mode = "coded"
[sensor]
preset = "grasshopper-icx285"
light_levels = [100, 300]
"""


def _doc(**changes) -> dict:
    doc = parse_toml(BASE, "the test spec")
    for key, value in changes.items():
        table, _, name = key.rpartition("__")
        target = doc[table] if table else doc
        if value is None:
            target.pop(name, None)
        else:
            target[name] = value
    return doc


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"capture__spp_per_px": 4}, ["[capture]", "spp_per_px", "valid keys"]),
        ({"capture__spp": 0}, ["[capture] spp", "[1,"]),
        ({"capture__crop": [1270, 0, 32, 24]}, ["crop", "inside the 1280x960"]),
        ({"sensor__light_levels": [-1]}, ["light_levels"]),
        ({"sensor__preset": "nope"}, ["[sensor] preset"]),
        ({"run": {"store": "sometimes"}}, ["[run] store", "auto, always, never"]),
        ({"seed": 1.5}, ["`seed`", "integer in [0,"]),
        ({"scenes": None}, ["`scenes` is missing"]),
        ({"scenes": []}, ["`scenes`", "non-empty"]),
        ({"scenes": ["trian"]}, ["`scenes`", "no scene 'trian'", "train"]),
        ({"scenes": {"family": "occluders", "seeds": [5, 2]}}, ["[scenes] seeds", "empty"]),
        ({"scenes": {"family": "occluders", "seeds": "x"}}, ["[scenes] seeds", "integer"]),
        ({"scenes": {"family": "occluders", "seeds": 2, "size": 3}}, ["[scenes]", "'size'"]),
        ({"cameras": [{"mode": "codd"}]}, ["[[cameras]] #1 mode", "did you mean 'coded'"]),
        ({"cameras": [{"mode": "coded"}, {"mode": "coded"}]}, ["names must differ"]),
        ({"capture__noise_ratio": 0.3}, ["spp and a noise target"]),
    ],
)
def test_spec_errors_name_the_key(changes, words):
    with pytest.raises(FileKeyError) as err:
        parse_spec(_doc(**changes))
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_family_seeds_become_scene_strings():
    count = parse_spec(_doc(scenes={"family": "occluders", "seeds": 3}))
    assert count.scenes == tuple(f"family:occluders:{s}" for s in range(3))
    ranged = parse_spec(_doc(scenes={"family": "occluders", "seeds": [10, 12], "params": {}}))
    assert ranged.scenes == ("family:occluders:10", "family:occluders:11", "family:occluders:12")
    assert ranged.family == "occluders" and ranged.family_params == {}


@pytest.mark.parametrize(
    "scenes, words",
    [
        ({"family": "occludrs", "seeds": 2}, ["[scenes] family 'occludrs'", "occluders"]),
        ({"family": "occluders", "seeds": 2, "params": {"depth_range_mm": [900, 400]}},
         ["[scenes] family 'occluders', params", "depth_range_mm"]),
        ({"family": "occluders", "seeds": 2, "params": {"colour": 1}}, ["colour"]),
    ],
)  # fmt: skip
def test_a_bad_family_or_parameter_is_refused_naming_it(scenes, words):
    with pytest.raises(FileKeyError) as err:
        parse_spec(_doc(scenes=scenes))
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_plan_counts_and_keys():
    plan = plan_dataset(parse_spec(_doc()))
    samples = plan.samples
    assert len(samples) == 2 * 3 * 2 == len(plan.renders) * 2
    assert len({s.id for s in samples}) == len({s.key for s in samples}) == len(samples)
    again = plan_dataset(parse_spec(_doc()))
    assert [s.key for s in again.samples] == [s.key for s in samples]
    assert [r.spec.seed for r in again.renders] == [r.spec.seed for r in plan.renders]
    other = plan_dataset(parse_spec(_doc(seed=4)))
    assert not {s.key for s in other.samples} & {s.key for s in samples}


def test_disk_bound_refused_before_any_work():
    doc = _doc(cameras=[{"name": "ref", "mode": "reference"}])  # no PSF: exact arithmetic
    # capture, sharp, noisy: 3 channels each; depth, object_id, raw, relative illumination: 1;
    # velocity: 2 -> 15 float32 channels, an 8-bit RGB preview, and the JSON allowance
    per = 4 * 15 * 32 * 24 + 3 * 32 * 24 + SIDECAR_BYTES
    total = 2 * 1 * 2 * per
    assert plan_dataset(parse_spec(doc)).disk_bytes == total
    doc["run"] = {"max_disk_gib": total / 2**30 * 0.99}
    with pytest.raises(ParameterError, match=r"max_disk_gib"):
        plan_dataset(parse_spec(doc))
    doc["run"] = {"max_disk_gib": total / 2**30 * 1.01}
    plan_dataset(parse_spec(doc))


def test_store_break_even_from_the_measured_ratios():
    even = break_even_cameras()
    (n4, r4), (n16, r16) = STORE_RATIOS[1], STORE_RATIOS[2]
    t = math.log(r4) / (math.log(r4) - math.log(r16))
    assert even == pytest.approx(math.exp(math.log(n4) + t * (math.log(n16) - math.log(n4))))
    assert 12 < even < 13
    assert use_store(parse_spec(_doc(run={"store": "never"}))) is False
    assert use_store(parse_spec(_doc(run={"store": "always"}))) is True


def test_cli_bad_spec_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(BASE.replace("spp = 4", "spp = -4"))
    assert main(["dataset", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[capture] spp" in err[0], err
    assert not (tmp_path / "out").exists()
    path.write_text("scenes = [")
    assert main(["dataset", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "not valid TOML" in capsys.readouterr().err


def test_auto_takes_stores_above_the_break_even_for_the_cameras_they_serve():
    """13 cameras per scene is above the measured break-even (12.6): a store per scene; the
    pinhole and Levin's moving camera are rendered directly (a store's rays cannot give them),
    and the store's samples' keys differ from the direct ones'."""
    cams = [{"name": f"c{i}", "mode": "coded"} for i in range(11)]
    cams += [{"name": "pin", "mode": "reference"}, {"name": "lev", "mode": "levin"}]
    assert use_store(parse_spec(_doc(cameras=cams))) is True
    assert use_store(parse_spec(_doc(cameras=cams[:12]))) is False
    plan = plan_dataset(parse_spec(_doc(cameras=cams)))
    via = {r.camera: r.via for r in plan.renders}
    assert via["pin"] == via["lev"] == "direct" and via["c0"] == "store"
    direct = plan_dataset(parse_spec(_doc(cameras=cams, run={"store": "never"})))
    keys = {s.id: s.key for s in direct.samples}
    for s in plan.samples:
        assert (keys[s.id] == s.key) == (s.camera in ("pin", "lev"))


def test_the_store_ratio_interpolates_the_measured_points():
    for n, r in STORE_RATIOS:
        assert store_ratio(n) == pytest.approx(r)
    assert store_ratio(8) == pytest.approx(math.sqrt(STORE_RATIOS[1][1] * STORE_RATIOS[2][1]))


@pytest.mark.parametrize(
    ("value", "words"),
    [(-1.0, ["[[cameras]] #3 lcos_switching_ms", "[0, 1000]"]),
     (5.0, ["lcos_switching_ms (5 ms)", "pattern's time"])],
)  # fmt: skip
def test_a_camera_lcos_switching_is_checked_before_any_work(value, words):
    """Out of range, or longer than the camera's pattern time (45 ms / 16 = 2.81 ms): one
    line naming the key, when the spec is read or planned."""
    doc = _doc()
    doc["cameras"][2]["lcos_switching_ms"] = value
    with pytest.raises(ParameterError) as e:
        plan_dataset(parse_spec(doc))
    assert all(w in str(e.value) for w in words), e.value
