"""What ``pacam optimize --lightfield`` writes beside design.toml: search.json, search.png and
report.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.outputs import write_json, write_text
from .outputs import save_figure


def write_outputs(out: Path, doc: dict, force: bool) -> list[Path]:
    """search.json, search.png and report.md."""
    return [
        write_json(out / "search.json", doc, force=force),
        save_figure(out / "search.png", lambda fig: _plot(fig, doc), force),
        write_text(out / "report.md", report(doc), force=force),
    ]


def _plot(fig, doc: dict) -> None:
    """The worst case against evaluations and seconds; the centres per pattern."""
    tr = np.array(doc["trace"], float)
    ax, ax2, ax3 = (fig.add_subplot(1, 3, i) for i in (1, 2, 3))
    ax.step(tr[:, 0], tr[:, 2], where="post")
    ax.set(xlabel="evaluations", ylabel="worst case over the stores (dB)",
           title="rendered objective")  # fmt: skip
    ax2.step(tr[:, 1] + doc["setup_s"], tr[:, 2], where="post")
    ax2.set(xlabel="seconds (with the stores' bases)", ylabel="worst case (dB)")
    n = len(doc["found_centres_mm"])
    k = np.arange(n)
    ax3.plot(k, doc["start_centres_mm"], "o-", label="start (the store's design)")
    ax3.plot(k, doc["found_centres_mm"], "s-", label="found")
    ax3.set(xlabel="pattern (time)", ylabel="opening centre x (mm)", title="schedule")
    ax3.legend(fontsize=7)
    for a in (ax, ax2, ax3):
        a.grid(alpha=0.3)


def report(doc: dict) -> str:
    """report.md: the search's result per store, its cost, and the fresh-render check."""
    lines = [
        "# pacam optimize --lightfield",
        "",
        f"Scored: {doc['scoring']}; sensor {doc['sensor']} at {doc['light_level']} "
        f"photons/px/ms, {doc['method']}, {doc['noise_draws']} noise draw(s).",
        "",
        "| store | scene | start (dB) | found (dB) | gain (dB) |",
        "|---|---|---|---|---|",
    ]
    for s, a, b in zip(doc["stores"], doc["start_psnr_moving_db"], doc["found_psnr_moving_db"]):
        lines.append(f"| {s['folder']} | {s['scene']} | {a:.2f} | {b:.2f} | {b - a:+.2f} |")
    lines += [
        f"| worst | | {doc['start_worst_db']:.2f} | {doc['found_worst_db']:.2f} | "
        f"{doc['found_worst_db'] - doc['start_worst_db']:+.2f} |",
        "",
        f"{doc['evaluations']} evaluations in {doc['trace'][-1][1]:.1f} s, after "
        f"{doc['setup_s']:.1f} s building the stores' bases (search.png: the worst case "
        "against evaluations and seconds).",
    ]
    fresh = doc.get("fresh")
    if fresh:
        lines += ["", "## Checked on fresh renders (new render seeds, new sensor draws)", "",
                  "| scene | start (dB, per seed) | found (dB, per seed) | gain (dB) | 95 % |",
                  "|---|---|---|---|---|"]  # fmt: skip
        for r in fresh["stores"] + [{"scene": "worst case", **fresh["worst"]}]:
            lines.append(
                f"| {r['scene']} | {_dbs(r['base_db'])} | {_dbs(r['found_db'])} | "
                f"{r['gain_db']:+.2f} | {_ci(r['gain_ci95_db'])} |"
            )
    return "\n".join(lines) + "\n"


def _dbs(values) -> str:
    return ", ".join(f"{v:.2f}" for v in values)


def _ci(ci) -> str:
    return "n/a (one seed)" if ci is None else f"[{ci[0]:+.2f}, {ci[1]:+.2f}]"
