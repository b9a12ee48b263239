"""Fingerprints of a set of small captures, to show that a refactor renders the same bits.

Each capture's image, layers, per-pattern images and Monte Carlo sigma are hashed, and its
record is kept as JSON with the timings taken out. Run it on two trees and compare the files:

    PYTHONPATH=/path/to/old/tree .venv/bin/python scripts/fingerprint_captures.py old.json
    .venv/bin/python scripts/fingerprint_captures.py new.json
    cmp old.json new.json

(issue 48: 15 cases, identical before and after the capture plan).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import sys
import tempfile
import warnings
from dataclasses import replace

import numpy as np


def scrub(x):
    """``x`` without what varies from run to run (seconds, versions)."""
    if isinstance(x, dict):
        return {k: scrub(v) for k, v in x.items() if not re.search(r"second|took|versions", k)}
    if isinstance(x, list):
        return [scrub(v) for v in x]
    if isinstance(x, str):
        return re.sub(r"\d+\.\d+ s\b", "T s", x)
    return x


def cases(folder: str) -> dict:
    from pacam_render.exposure import CaptureSpec
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import write_design

    design = os.path.join(folder, "d.toml")
    write_design(design, prototype().with_(R_mm=2.5, name="mine"))
    schedule = os.path.join(os.path.dirname(__file__), "..", "docs", "optimize", "icx285")
    base = dict(scene="train", width=48, height=36, spp=8)
    optics = dict(relative_illumination="cos4")
    return {
        "coded_geo": CaptureSpec(mode="coded", **base),
        "coded_optics": CaptureSpec(mode="coded", diffraction="on", **optics, **base),
        "coded_auto": CaptureSpec(mode="coded", diffraction="auto", **optics, **base),
        "normal_cos4": CaptureSpec(mode="normal", **optics, **base),
        "short": CaptureSpec(mode="short", **base),
        "levin": CaptureSpec(mode="levin", **base),
        "flutter_diff": CaptureSpec(mode="flutter", diffraction="on", **base),
        "reference": CaptureSpec(mode="reference", **base),
        "grey_cover": CaptureSpec(mode="coded", grey=True, cover_px_per_ms=1.4, **base),
        "lcos": CaptureSpec(
            mode="coded", lcos_contrast=50.0, lcos_switching_ms=0.3, per_pattern=True, **base
        ),  # fmt: skip
        "crop_full": CaptureSpec(
            mode="coded", width=1280, height=960, crop=(600, 450, 40, 30), spp=8, diffraction="on"
        ),  # fmt: skip
        "designfile": CaptureSpec(mode="coded", design=design, **base),
        "designfile_depth_normal": CaptureSpec(
            mode="normal", design=design, object_depth_mm=700.0, **optics, **base
        ),  # fmt: skip
        "cover_normal": CaptureSpec(mode="normal", cover_px_per_ms=1.0, **base),
        "schedule": CaptureSpec(
            mode="coded", schedule=os.path.join(schedule, "schedule.json"), diffraction="on", **base
        ),  # fmt: skip
    }


def synthesised(folder: str) -> dict:
    """Captures synthesised from one light-field store (issue 55: the second producer)."""
    from pacam_render.exposure import CaptureSpec
    from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize

    base = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(456, 410, 48, 32),
                                 spp=16, passes=4, seed=1)  # fmt: skip
    designs = (base, replace(base, mode="normal"))
    store = render_lightfield(StoreSpec(base, designs=designs), os.path.join(folder, "lf"),
                              progress=False)  # fmt: skip
    specs = {
        "syn_coded": base,
        "syn_normal_cos4": replace(base, mode="normal", relative_illumination="cos4"),
        "syn_cover": replace(base, cover_px_per_ms=1.4),
    }
    return {name: (lambda s=s: synthesize(store, s, progress=False)) for name, s in specs.items()}


def main(out: str) -> None:
    from pacam_render.exposure import render_capture

    warnings.simplefilter("ignore")
    res = {}
    folder = tempfile.mkdtemp()
    makers = {n: (lambda s=s: render_capture(s, progress=False)) for n, s in cases(folder).items()}
    if "--synthesis" in sys.argv:  # the light-field producer's captures too
        makers.update(synthesised(folder))
    for name, make in makers.items():
        cap = make()
        h = hashlib.sha256(np.ascontiguousarray(cap.image).tobytes())
        for k in sorted(cap.extra_layers):
            h.update(k.encode() + np.ascontiguousarray(cap.extra_layers[k]).tobytes())
        for k in sorted(cap.patterns):
            h.update(np.ascontiguousarray(cap.patterns[k]).tobytes())
        if cap.mc_sigma is not None:
            h.update(np.ascontiguousarray(cap.mc_sigma).tobytes())
        record = scrub(json.loads(json.dumps(cap.record.to_json())))
        record["spec"].pop("design", None)  # a temporary path
        record["spec"].pop("schedule", None)
        record.get("lightfield", {}).pop("store", None)
        res[name] = {"arrays": h.hexdigest(), "record": record}
        print(name, h.hexdigest()[:16], flush=True)
    with open(out, "w") as f:
        json.dump(res, f, indent=1, sort_keys=True)


if __name__ == "__main__":
    main(sys.argv[1])  # --synthesis: add captures synthesised from a light-field store
