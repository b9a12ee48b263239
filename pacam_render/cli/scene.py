"""``pacam scene generate``: a seeded scene of a family (:mod:`pacam_render.scenes.family`),
written as ``scene.xml``, ``scene.motion.json`` and the card ``scene.json``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..errors import ParameterError
from ..scenes.family.spec import FAMILIES, TEXTURE_SOURCES, check_family, check_seed
from ..scenes.family.write import generate_scene
from .common import add_force, add_out


def add(sub) -> None:
    p = sub.add_parser("scene", help="generate seeded scenes of a family (occluders, ...)")
    ssub = p.add_subparsers(dest="scene_command", required=True, metavar="ACTION")
    g = ssub.add_parser(
        "generate",
        help="draw one scene of a family from a seed and write it into DIR",
        description="Draw scene SEED of a family and write DIR/scene.xml, scene.motion.json "
        "(which every command reads as a scene), textures/ and the card DIR/scene.json. The "
        "same seed and flags give byte-identical files. Defaults suit the prototype "
        "(1280x960, 2T = 45 ms); speeds and sizes are px at that scale.",
    )
    g.add_argument("--family", required=True, help=f"one of {', '.join(FAMILIES)}")
    g.add_argument("--seed", required=True, metavar="S", help="a non-negative integer")
    add_out(g, help="the scene's folder")
    ranges = (
        ("--depth-range", "MIN,MAX", "object depths, mm (occluders 400,900; depths 250,2500)"),
        ("--speed-range", "MIN,MAX", "|image speed|, px/ms; both signs are drawn "
         "(occluders 0.2,1.4; depths 0,0.3; still 0,0)"),
        ("--objects", "MIN,MAX", "how many objects (occluders 2,6; depths 3,6; still 2,6)"),
        ("--size-range", "MIN,MAX", "object size, px at its depth (default 40,120)"),
        ("--window", "X,Y,W,H", "the window of the 1280x960 sensor the objects cross "
         "(default 480,360,320,240)"),
    )  # fmt: skip
    for flag, metavar, text in ranges:
        g.add_argument(flag, metavar=metavar, help=text)
    g.add_argument(
        "--direction-spread",
        type=float,
        metavar="DEG",
        help="directions drawn within +-DEG of the horizontal (default 0)",
    )
    g.add_argument(
        "--textures",
        help=f"{' or '.join(TEXTURE_SOURCES)} (scikit-image's bundled photographs; default "
        "procedural)",
    )
    g.add_argument(
        "--wall-depth", type=float, metavar="MM", help="the wall's depth (occluders 1000 mm)"
    )
    add_force(g, "overwrite the scene files in DIR")
    p.set_defaults(func=run)


def _numbers(flag: str, text: str | None, n: int, kind=float) -> tuple | None:
    """``text`` as ``n`` comma-separated numbers, or None if not given."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        if len(parts) != n:
            raise ValueError
        values = tuple(float(x) for x in parts)
        if kind is int and any(v != int(v) for v in values):
            raise ValueError
    except ValueError:
        what = "integers" if kind is int else "numbers"
        raise ParameterError(f"{flag} must be {n} comma-separated {what}, got {text!r}") from None
    return tuple(kind(v) for v in values)


def params_from_args(args: argparse.Namespace) -> dict:
    """The library's parameters from the flags given (left out: the family's default)."""
    params = {
        "depth_range_mm": _numbers("--depth-range", args.depth_range, 2),
        "speed_range_px_per_ms": _numbers("--speed-range", args.speed_range, 2),
        "object_count": _numbers("--objects", args.objects, 2, int),
        "size_range_px": _numbers("--size-range", args.size_range, 2),
        "window": _numbers("--window", args.window, 4, int),
        "direction_spread_deg": args.direction_spread,
        "textures": args.textures,
        "wall_depth_mm": args.wall_depth,
    }
    return {k: v for k, v in params.items() if v is not None}


def summary(card: dict, xml: Path) -> list[str]:
    """The lines ``pacam scene generate`` prints: the objects, the events and the files."""
    p = card["parameters"]
    lines = [
        f"family {card['family']} v{card['family_version']}, seed {card['seed']} (draw "
        f"{card['draw_attempt']}): {len(card['objects'])} objects before a wall at "
        f"{card['wall']['centre_mm'][2]:g} mm, window {','.join(map(str, p['window']))}"
    ]
    for o in card["objects"]:
        w, h = o["size_px"]
        lines.append(
            f"  {o['id']:<9} {o['shape']:<9} depth {o['depth_mm']:7.1f} mm  size {w:5.1f} x "
            f"{h:5.1f} px  speed {o['image_speed_px_per_ms']:+.3f} px/ms at "
            f"{o['direction_deg']:+.1f} deg  {o['texture']['kind']}"
        )
    events = card["occlusion_events"]
    lines.append(f"occlusion events inside the window: {len(events)}")
    for e in events:
        x0, y0, x1, y1 = e["region_px"]
        lines.append(
            f"  {e['front']} in front of {e['behind']}: {e['first_ms']:+.2f} to "
            f"{e['last_ms']:+.2f} ms, region x {x0}-{x1} y {y0}-{y1} px, up to "
            f"{e['max_overlap_px']} px, relative {e['relative_speed_px_per_ms']:.3f} px/ms"
            + (", passes" if e["passes"] else "")
        )
    lines.append(
        f"wrote {xml}, {xml.with_name('scene.motion.json')}, {xml.with_name('scene.json')}"
    )
    lines.append(f"digest {card['digest']}")
    return lines


def run(args: argparse.Namespace) -> int:
    family, seed = check_family(args.family), check_seed(args.seed)
    xml = generate_scene(family, seed, Path(args.out), force=args.force, **params_from_args(args))
    card = json.loads(xml.with_name("scene.json").read_text())
    print("\n".join(summary(card, xml)))
    return 0
