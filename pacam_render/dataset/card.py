"""``DIR/card.md``: the dataset's data card.

It holds the counts (samples ok and failed, per camera and light level), histograms as PNG
pictures in ``DIR/card/`` (the render error of every sample; and, where the scenes are a
family's, the objects' depths, image speeds and the share of objects occluded, read from each
generated scene's ``scene.json`` card), the render time, the spec and the versions.
"""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

from ..exposure.assemble import versions
from ..io.outputs import save_figure, write_text
from .spec import DatasetSpec

CARD = "card.md"
PICTURES = "card"

OBJECT_KEYS = {
    "depth": ("depth_mm", "depth objects (mm)"),
    "speed": ("image_speed_px_per_ms", "image speed of objects (px/ms)"),
}
"""Histograms of the scene cards' objects (:mod:`pacam_render.scenes.family`'s ``scene.json``):
picture name -> (the object's key, the axis)."""


def write_card(out, spec: DatasetSpec, rows: list[dict], scene_cards: list[dict]) -> Path:
    """Write ``out/card.md`` and its pictures; the card's path."""
    out = Path(out)
    pictures = _pictures(out / PICTURES, rows, scene_cards)
    ok = [r for r in rows if r["status"] == "ok"]
    lines = [
        f"# Dataset card: {spec.name}",
        "",
        f"{len(ok)} samples ok, {len(rows) - len(ok)} failed, of {spec.n_samples} planned: "
        f"{len(spec.scenes)} scenes x {len(spec.cameras)} cameras x {len(spec.light_levels)} "
        "light levels.",
        "",
        *_counts(rows),
        "",
        f"Render time, summed over renders: {_render_seconds(ok):.1f} s.",
        "",
        *[f"![{name}]({PICTURES}/{name}.png)" for name in pictures],
        "",
        "## Spec",
        "",
        "```json",
        json.dumps(spec.source, indent=2, sort_keys=True, default=str),
        "```",
        "",
        "## Versions",
        "",
        *[f"- {k} {v}" for k, v in versions().items()],
        "",
    ]
    return write_text(out / CARD, "\n".join(lines), force=True)


def _counts(rows: list[dict]) -> list[str]:
    """A Markdown table: samples ok / failed per camera and light level."""
    ok = Counter((r["camera"], float(r["light_level"])) for r in rows if r["status"] == "ok")
    bad = Counter((r["camera"], float(r["light_level"])) for r in rows if r["status"] != "ok")
    lines = ["| camera | light level (photons/px/ms) | ok | failed |", "|---|---|---|---|"]
    for cam, level in sorted(set(ok) | set(bad)):
        lines.append(f"| {cam} | {level:g} | {ok[(cam, level)]} | {bad[(cam, level)]} |")
    return lines


def _render_seconds(rows: list[dict]) -> float:
    """Seconds of the renders: a render's seconds once, whatever its light levels."""
    seen = {(r["scene"], r["camera"]): float(r["seconds"]) for r in rows if r["seconds"] != ""}
    return sum(seen.values())


def object_values(scene_cards: list[dict], key: str) -> list[float]:
    """Every object's ``key`` over the scene cards (objects under ``objects``)."""
    values = []
    for card in scene_cards:
        for obj in card.get("objects", []):
            if isinstance(obj, dict) and isinstance(obj.get(key), (int, float)):
                values.append(float(obj[key]))
    return values


def occlusion_share(card: dict) -> float | None:
    """The share of a scene card's objects in an occlusion event (the card's
    ``occlusion_events``, each naming its ``front`` and ``behind`` objects); None without
    objects."""
    objs = [o.get("id") for o in card.get("objects", []) if isinstance(o, dict)]
    if not objs:
        return None
    events = [e for e in card.get("occlusion_events", []) if isinstance(e, dict)]
    hit = {e.get(k) for e in events for k in ("front", "behind")}
    return sum(o in hit for o in objs) / len(objs)


def _pictures(folder: Path, rows: list[dict], scene_cards: list[dict]) -> list[str]:
    """Write the histograms that have data; their names."""
    data = {"render_error": ([float(r["render_error"]) for r in rows if r["status"] == "ok"],
                             "render error: Monte Carlo sigma (the capture's units)")}  # fmt: skip
    for name, (key, label) in OBJECT_KEYS.items():
        data[name] = (object_values(scene_cards, key), label)
    shares = [s for s in map(occlusion_share, scene_cards) if s is not None]
    data["occlusion_share"] = (shares, "share of a scene's objects occluded")
    written = []
    for name, (values, label) in data.items():
        if values:
            _histogram(folder / f"{name}.png", values, label)
            written.append(name)
    return written


def _histogram(path: Path, values: list[float], label: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.hist(values, bins=min(30, max(5, len(values) // 3)))
    ax.set_xlabel(label)
    ax.set_ylabel("count")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
