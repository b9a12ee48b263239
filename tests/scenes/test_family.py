"""Seeded scene families (issue 57, item 1): determinism, the drawn ranges, the guaranteed
occlusion checked by brute force, loading by name, the CLI, and a tiny render.

The checks of geometry are independent of the code under test: image positions come from the
thin-lens projection in closed form (u = W/2 - f x / z, f = (W/2) / tan(fov/2)), and occlusion
from pixel sampling of the cards' objects over the whole window.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.model import paper
from pacam_render.scenes import load_scene
from pacam_render.scenes.family import (
    FAMILIES,
    family_scene,
    generate_scene,
    parse_family_name,
    resolve_params,
)
from tests.doc_blocks import shown_commands

ROOT = Path(__file__).resolve().parents[2]
F_PX = 0.5 * paper.WIDTH_PX / math.tan(math.radians(paper.FOV_DEG) / 2)
T_MS = 0.5 * paper.EXPOSURE_MS


def _files(d: Path) -> dict[str, bytes]:
    return {
        p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()
    }


def _card(xml: Path) -> dict:
    return json.loads(xml.with_name("scene.json").read_text())


def _u_px(p_mm) -> np.ndarray:
    """Thin-lens (pinhole) image position (u, v) of a point, closed form."""
    x, y, z = p_mm
    return np.array([paper.WIDTH_PX / 2 - F_PX * x / z, paper.HEIGHT_PX / 2 - F_PX * y / z])


@pytest.mark.parametrize("family", list(FAMILIES))
def test_same_seed_same_bytes_different_seeds_differ(tmp_path, family):
    a = _files(generate_scene(family, 7, tmp_path / "a").parent)
    b = _files(generate_scene(family, 7, tmp_path / "b").parent)
    c = _files(generate_scene(family, 8, tmp_path / "c").parent)
    assert a == b
    assert a["scene.xml"] != c["scene.xml"]
    assert {"scene.xml", "scene.motion.json", "scene.json", "textures/wall.png"} <= set(a)


def test_photo_textures_are_deterministic_too(tmp_path):
    a = generate_scene("still", 2, tmp_path / "a", textures="photos")
    b = generate_scene("still", 2, tmp_path / "b", textures="photos")
    assert _files(a.parent) == _files(b.parent)
    assert all(o["texture"]["kind"].startswith("skimage:") for o in _card(a)["objects"])


def test_the_card_digest_covers_the_scene_files(tmp_path):
    import hashlib

    xml = generate_scene("occluders", 1, tmp_path / "s")
    card = _card(xml)
    total = hashlib.sha256()
    for name in sorted(card["files"]):
        data = (xml.parent / name).read_bytes()
        assert hashlib.sha256(data).hexdigest() == card["files"][name]
        total.update(name.encode() + b"\0" + data)
    assert card["digest"] == total.hexdigest()
    assert len(card["files"]) == 2 + len(card["objects"]) + 1  # xml, motion, textures, wall


@pytest.mark.parametrize("family", list(FAMILIES))
def test_drawn_objects_lie_in_the_asked_ranges(tmp_path, family):
    p = resolve_params(family)
    for seed in range(6):
        card = _card(generate_scene(family, seed, tmp_path / str(seed)))
        lo, hi = p["object_count"]
        assert lo <= len(card["objects"]) <= hi
        motion = json.loads((tmp_path / str(seed) / "scene.motion.json").read_text())
        for o in card["objects"]:
            assert p["depth_range_mm"][0] <= o["depth_mm"] <= p["depth_range_mm"][1]
            speed = abs(o["image_speed_px_per_ms"])
            assert p["speed_range_px_per_ms"][0] <= speed <= p["speed_range_px_per_ms"][1]
            assert all(p["size_range_px"][0] <= s <= p["size_range_px"][1] for s in o["size_px"])
            v = motion["shapes"].get(o["id"], {}).get("velocity_mm_per_ms", [0.0, 0.0, 0.0])
            c0 = np.array(o["centre_mm"])
            du_dv = _u_px(c0 + np.array(v)) - _u_px(c0)  # 1 ms later, projected
            assert np.hypot(*du_dv) == pytest.approx(speed, abs=1e-6)
            assert math.copysign(1, du_dv[0]) == math.copysign(1, o["image_speed_px_per_ms"]) or (
                speed == 0
            )
            x, y, w, h = p["window"]
            u, v0 = _u_px(c0)
            assert x <= u <= x + w and y <= v0 <= y + h  # it crosses the window
            assert motion["depths_mm"][o["id"]] == o["depth_mm"]
        assert card["wall"]["centre_mm"][2] == p["wall_depth_mm"]


def test_still_has_no_motion(tmp_path):
    for seed in range(4):
        xml = generate_scene("still", seed, tmp_path / str(seed))
        motion = json.loads(xml.with_name("scene.motion.json").read_text())
        assert motion["shapes"] == {}
        assert all(o["velocity_mm_per_ms"] == [0, 0, 0] for o in _card(xml)["objects"])


def _inside(o: dict, u: np.ndarray, v: np.ndarray, t_ms: float) -> np.ndarray:
    """Pixel centres inside the object's central fronto-parallel section at time t."""
    c = np.array(o["centre_mm"]) + t_ms * np.array(o["velocity_mm_per_ms"])
    uc, vc = _u_px(c)
    half_w, half_h = 0.5 * F_PX * np.array(o["size_mm"][:2]) / c[2]
    if o["shape"] == "sphere":
        return (u - uc) ** 2 + (v - vc) ** 2 <= half_w**2
    return (np.abs(u - uc) <= half_w) & (np.abs(v - vc) <= half_h)


def brute_force_occlusions(card: dict) -> dict[tuple[str, str], list[float]]:
    """(front, behind) -> the sampled times (1 ms apart) at which a nearer object's section
    covers a farther one's at a pixel centre of the window, and they move relative to each
    other."""
    x, y, w, h = card["parameters"]["window"]
    u, v = np.meshgrid(np.arange(x, x + w) + 0.5, np.arange(y, y + h) + 0.5)
    objs = sorted(card["objects"], key=lambda o: o["depth_mm"])
    found: dict[tuple[str, str], list[float]] = {}
    for t in np.arange(-T_MS, T_MS + 1e-9, 1.0):
        masks = [_inside(o, u, v, t) for o in objs]
        for i, a in enumerate(objs):
            for j in range(i + 1, len(objs)):
                b = objs[j]
                rel = np.subtract(a["image_velocity_px_per_ms"], b["image_velocity_px_per_ms"])
                if np.hypot(*rel) * 2 * T_MS >= 1.0 and np.any(masks[i] & masks[j]):
                    found.setdefault((a["id"], b["id"]), []).append(float(t))
    return found


def test_occluders_always_occlude_inside_the_window(tmp_path):
    for seed in range(20):
        card = _card(generate_scene("occluders", seed, tmp_path / str(seed)))
        found = brute_force_occlusions(card)
        assert found, f"seed {seed}: no occlusion by brute force"
        passing = [e for e in card["occlusion_events"] if e["passes"]]
        assert passing, seed
        for e in passing:
            times = found[(e["front"], e["behind"])]
            assert e["first_ms"] - 1 <= min(times) and max(times) <= e["last_ms"] + 1, seed
            x0, y0, x1, y1 = e["region_px"]
            wx, wy, ww, wh = card["parameters"]["window"]
            assert wx <= x0 < x1 <= wx + ww and wy <= y0 < y1 <= wy + wh


def test_load_scene_by_family_name_matches_the_card(tmp_path, monkeypatch):
    monkeypatch.setenv("PACAM_CACHE", str(tmp_path / "cache"))
    desc = load_scene("family:occluders:3")
    xml = family_scene("family:occluders:3")
    assert xml == family_scene("occluders", 3)  # the same cached folder
    assert xml.is_relative_to(tmp_path / "cache" / "families")
    card = _card(xml)
    assert desc.name == "family:occluders:3"
    assert sorted(desc.bboxes_mm) == sorted([o["id"] for o in card["objects"]] + ["wall"])
    for o in card["objects"]:
        got = desc.motions[o["id"]].velocity_mm_per_ms
        assert np.allclose(got, o["velocity_mm_per_ms"])
        assert desc.depths_mm[o["id"]] == o["depth_mm"]
    fresh = generate_scene("occluders", 3, tmp_path / "fresh")
    assert _files(fresh.parent) == _files(xml.parent)


@pytest.mark.parametrize(
    "name, message",
    [
        ("family:nope:3", r"unknown `family` 'nope'.*occluders, depths, still"),
        ("family:occluders:x", r"seed of scene 'family:occluders:x'.*'x'"),
        ("family:occluders:-1", r"seed of scene"),
        ("family:occluders", r"family:NAME:SEED"),
    ],
)
def test_bad_family_names_are_clear(name, message):
    with pytest.raises(ParameterError, match=message):
        load_scene(name)
    with pytest.raises(ParameterError, match=message):
        parse_family_name(name)


@pytest.mark.parametrize(
    "params, name",
    [
        ({"depth_range_mm": (900, 400)}, "depth_range_mm"),
        ({"depth_range_mm": (-5, 400)}, "depth_range_mm"),
        ({"speed_range_px_per_ms": (0, 50)}, "speed_range_px_per_ms"),
        ({"speed_range_px_per_ms": (-1, 1)}, "speed_range_px_per_ms"),
        ({"object_count": (1, 3)}, "object_count"),
        ({"object_count": (2, 99)}, "object_count"),
        ({"direction_spread_deg": 120}, "direction_spread_deg"),
        ({"wall_depth_mm": 500}, "wall_depth_mm"),
        ({"window": (0, 0, 2000, 100)}, "`window`"),
        ({"textures": "paint"}, "`textures`"),
        ({"size_range_px": (1, 10)}, "size_range_px"),
        ({"colour": 3}, "colour"),
    ],
)
def test_bad_parameters_name_themselves(tmp_path, params, name):
    with pytest.raises(ParameterError, match=name.replace("`", r"\`")):
        generate_scene("occluders", 1, tmp_path / "s", **params)
    assert not (tmp_path / "s").exists()  # refused before any work


def test_still_refuses_motion_and_seeds_must_be_integers(tmp_path):
    with pytest.raises(ParameterError, match=r"speed_range_px_per_ms must be \(0, 0\)"):
        generate_scene("still", 1, tmp_path / "s", speed_range_px_per_ms=(0, 1))
    for seed in (-1, 1.5, True, "a"):
        with pytest.raises(ParameterError, match="seed"):
            generate_scene("still", seed, tmp_path / "s")


def test_cli_generate_refuses_overwrite_and_bad_flags(tmp_path, capsys):
    out = tmp_path / "scene"
    args = ["scene", "generate", "--family", "occluders", "--seed", "4", "--out", str(out)]
    assert main([*args, "--speed-range", "0.2,1.0", "--objects", "2,4"]) == 0
    printed = capsys.readouterr().out
    card = _card(out / "scene.xml")
    assert f"digest {card['digest']}" in printed and "in front of" in printed
    assert 2 <= len(card["objects"]) <= 4
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "already holds results" in err and "--force" in err
    assert main([*args, "--force"]) == 0
    capsys.readouterr()
    for bad, words in [
        (["--depth-range", "400"], "--depth-range must be 2 comma-separated numbers"),
        (["--speed-range", "0,40"], "--speed-range max must be <="),
        (["--objects", "2.5,3"], "--objects must be 2 comma-separated integers"),
        (["--window", "0,0,2000,10"], "--window w must be"),
        (["--wall-depth", "300"], "--wall-depth must be >"),
        (["--textures", "paint"], "--textures must be one of procedural, photos"),
    ]:
        assert main([*args, "--force", *bad]) == 2, bad
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, (bad, err)
    with pytest.raises(SystemExit) as exc:
        main([*args, "--no-such-flag"])
    assert exc.value.code == 2


def test_the_how_to_prints_what_it_shows(tmp_path, capsys, monkeypatch):
    """docs/howto/scene_family.md: its first console block, run in a fresh folder, prints the
    lines it shows, byte for byte (the scene is deterministic)."""
    monkeypatch.chdir(tmp_path)
    for cmd, shown in shown_commands(ROOT / "docs" / "howto" / "scene_family.md", "console"):
        words = cmd.split()
        assert words[0] == "pacam"
        assert main(words[1:]) == 0, cmd
        assert capsys.readouterr().out.splitlines()[: len(shown)] == shown


@pytest.mark.render
def test_a_family_scene_renders_by_name(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PACAM_CACHE", str(tmp_path / "cache"))
    card = _card(family_scene("family:occluders:3"))
    e = next(e for e in card["occlusion_events"] if e["passes"])
    x0, y0 = e["region_px"][:2]
    crop = f"{x0},{y0},32,32"
    args = ["render", "family:occluders:3", "--mode", "coded", "--crop", crop, "--spp", "4"]
    assert main([*args, "--quiet", "--out", str(tmp_path / "out")]) == 0
    record = json.loads((tmp_path / "out" / "capture.json").read_text())
    assert "family:occluders:3" in json.dumps(record)
    assert (tmp_path / "out" / "capture.exr").is_file()


def test_a_cylinder_is_the_card_s_upright_cylinder_and_loads_without_mitsuba_warnings(capfd):
    """Seed 13's object_3: written as ``p0``/``p1`` (family v1), Mitsuba's float32 frame left a
    2.9e-6 residue that it reported as shear and non-uniform scaling on every load. Its
    to_world is now the card's cylinder exactly: radius size/2 in x and z, length the height
    along +y from centre - height/2 (Mitsuba's unit cylinder runs 0 to 1 along z)."""
    import mitsuba as mi

    from pacam_render.render.backend import select_variant

    select_variant()
    xml = Path(family_scene("occluders", 13))
    o = next(o for o in _card(xml)["objects"] if o["id"] == "object_3")
    assert o["shape"] == "cylinder"
    capfd.readouterr()
    scene = load_scene(str(xml)).load()
    assert "Cylinder" not in "".join(capfd.readouterr())  # Mitsuba logs to stdout
    m = np.array(mi.traverse(scene)["object_3.to_world"].matrix, float).reshape(4, 4)
    (x, y, z), (w, h, _) = o["centre_mm"], o["size_mm"]
    for local, world in (((0, 0, 0), (x, y - h / 2, z)), ((0, 0, 1), (x, y + h / 2, z)),
                         ((1, 0, 0), (x + w / 2, y - h / 2, z)),
                         ((0, 1, 0), (x, y - h / 2, z - w / 2))):  # fmt: skip
        assert np.allclose(m @ [*local, 1.0], [*world, 1.0], atol=1e-4)
