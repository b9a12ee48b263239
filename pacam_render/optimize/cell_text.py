"""report.md of a cell-basis search (:mod:`.cell_run`): the objective in words, the starts, the
choice (:mod:`.cell_select`), the stores' render noise against the sensor's, the training
table and the held-out table with its paired intervals."""

from __future__ import annotations

import math

from ..lightfield.synthesis import RENDER_NOISE_SHARE
from .cell_objective import WORST_SOFTNESS_DB
from .cell_report import SCORES, markdown
from .cell_select import MIN_SIDE_PASSES, PROTOTYPE


def _what(p) -> str:
    """The objective in words, with how it is pooled over the stores."""
    what = ("moving objects' PSNR" if p.objective == "moving"
            else f"(moving PSNR + {p.weight:g} still PSNR) / {1 + p.weight:g}")  # fmt: skip
    if p.aggregate == "worst":
        return (f"{what}: the prototype's mean over the stores plus the soft minimum "
                f"(tau {WORST_SOFTNESS_DB:g} dB) of each store's gain over it")  # fmt: skip
    return f"{what}, mean over the stores"


def _starts(p, m: dict) -> str:
    """The starts' model dB in words."""
    if p.space == "discs":
        return ("Starts (name, dB, R mm): " + "; ".join(
            f"{s[0]} {s[1]:.2f} {m['R_mm'][s[0]]:.4g}" for s in m["starts"]) + ".")  # fmt: skip
    return ("Starts (name, relaxed dB, binary dB): "
            + "; ".join(f"{s[0]} {s[1]:.2f}/{s[2]:.2f}" for s in m["starts"]) + ".")  # fmt: skip


def _choice_text(p, doc: dict) -> str:
    """Which design was written, and why (:mod:`.cell_select`)."""
    c = doc["choice"]
    sc = {k: v for k, v in c["scores"].items()}
    best = max(sc, key=lambda k: sc[k]["value_db"])
    rule = (
        ""
        if p.max_still_loss_db is None
        else (f"; eligible: still regions within {p.max_still_loss_db:g} dB of the prototype's")
    )
    ps = doc["passes"]
    where = ("the stores' passes the search did not read "
             f"({', '.join(map(str, ps['choice']))}; it searched on "
             f"{', '.join(map(str, ps['search']))})" if ps["choice"] else
             "the training stores' own samples, which the search read: it may have fitted their "
             f"Monte Carlo noise (give stores of at least {2 * MIN_SIDE_PASSES} passes to "
             "choose on others)")  # fmt: skip
    pooled = ("soft minimum of the gains over the prototype" if p.aggregate == "worst"
              else "mean over the stores")  # fmt: skip
    line = f"Chosen with the real pipeline on {where} (the search's score, {pooled}{rule}): "
    line += "; ".join(f"{k} {v['value_db']:.2f} dB" + ("" if v["eligible"] else " (not eligible)")
                      for k, v in sc.items())  # fmt: skip
    if c["chosen"] == PROTOTYPE:
        why = "none eligible beat it" if best != PROTOTYPE else "no start beat it"
        return line + f". **Kept the prototype** ({why}): design.toml is the store's design."
    return line + f". Written: the result from start {c['chosen']!r}."


def _noise_text(p, doc: dict) -> str:
    """The stores' render noise against the sensor's, and what it means for the ranking."""
    r = [x for x in doc["store_noise"] if math.isfinite(x)]
    if not r:
        return ""
    span = f"{min(r):.2g}x" if min(r) == max(r) else f"{min(r):.2g}-{max(r):.2g}x"
    head = (f"The stores' captures carry render noise at {span} the sensor's ({p.sensor} at "
            f"{p.light_level:g} photons/px/ms).")  # fmt: skip
    if max(r) <= RENDER_NOISE_SHARE:
        return head + f" Under {RENDER_NOISE_SHARE:g}x: the camera's own regime."
    return head + (f" Over {RENDER_NOISE_SHARE:g}x, the designs are ranked in the render's "
                   "noise, not the camera's, which can reorder them (the notes on stderr say "
                   "how many samples per pass bring it under).")  # fmt: skip


def _held_text(doc: dict) -> list[str]:
    """The held-out table and the paired intervals, or where to check a design."""
    if not doc["held_out"]:
        return ["These are the training stores: check a design on scenes it has not seen "
                "(--held-out, or fresh renders: benchmarks/bench_bitmap_design.py)."]  # fmt: skip
    out = [markdown(doc["held_out"], "Held-out stores (scenes the search never saw)"),
           "Found design minus the prototype, paired per held-out store, mean [95 % "
           "Student-t interval] (n: the stores with pixels of that kind):", ""]  # fmt: skip
    for k, label in zip(SCORES, ("moving", "still", "whole")):
        d = doc["held_out_vs_prototype"][k]
        out.append(
            f"- {label}: "
            + (
                "n/a (fewer than 2 stores score it)"
                if d is None
                else f"{d[0]:+.2f} dB [{d[1]:+.2f}, {d[2]:+.2f}], n = {d[3]}"
            )
        )
    return out


def _focus_text(p, doc: dict) -> str:
    """Where the search focused, and the written design's focus."""
    if not p.focus_mm:
        return ""
    at = ", ".join(f"{f:g}" for f in p.focus_mm)
    return (
        f" Searched at the store design's focus and at {at} mm (each from the store's "
        f"design refocused there); design.toml focuses at {doc['design_focus_mm']:.0f} mm."
    )


def report_text(p, doc: dict) -> str:
    """report.md."""
    m = doc["model_db"]
    return "\n".join([
        f"# pacam optimize --lightfield --space {p.space} ({p.cells}x{p.cells} cells, light "
        f"{p.light})", "",
        f"Model objective ({len(p.stores)} store(s), {_what(p)}): found "
        f"{m['found']:.2f} dB; {doc['evaluations']} evaluations in {doc['search_s']:.1f} s "
        f"after {doc['setup_s']:.1f} s of setup. " + _starts(p, m) + _focus_text(p, doc), "",
        markdown(doc["train"], "Scored with the real pipeline on the stores' syntheses"),
        _choice_text(p, doc), "",
        _noise_text(p, doc), "",
        f"Each capture through {p.noise_draws} sensor draw(s) of {p.sensor} at "
        f"{p.light_level:g} photons/px/ms, Wiener with the design's s = 0 kernel told the "
        "sensor's and the render's noise, scored by score_capture. Invariant range: the "
        "smallest fitted range over the moving objects (n/a: a design with no parabola).", "",
        *_held_text(doc),
    ]) + "\n"  # fmt: skip
