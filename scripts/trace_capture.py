"""Follow one capture's spec through the package: which modules the calls that take it pass
through (issue 48's measure of the house).

Every Python call made while ``render_capture`` renders a tiny capture (diffraction ``auto``,
cos^4, a design file) is watched with ``sys.setprofile``; a call counts when one of its
arguments is the capture's spec or its plan (a ``CaptureSpec`` or ``CapturePlan``; with
``--with-designs``, or a ``CameraDesign``). Printed:
the calls ("stays"), the modules they are in, the calls that enter each subpackage, and the
calls made from a lower subpackage into a higher one ("climbs", by ``tests/test_architecture``'s
LAYERS). Run it from the project root: ``.venv/bin/python scripts/trace_capture.py``.
"""

from __future__ import annotations

import collections
import os
import sys
import tempfile
import warnings

LAYERS = ("errors", "limits", "io", "model", "wave", "psf", "render", "scenes", "capture",
          "sensor", "restore", "exposure", "psf_render", "lightfield", "optimize", "study",
          "experiments", "cli")  # fmt: skip
TRACKED = ("CaptureSpec", "CapturePlan")
"""What a counted call takes; ``--with-designs`` adds the cameras resolved from it."""


def _floor(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def main() -> None:
    from pacam_render.exposure.direct import render_capture
    from pacam_render.exposure.spec import CaptureSpec
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import write_design

    tracked = TRACKED + (("CameraDesign",) if "--with-designs" in sys.argv else ())
    warnings.simplefilter("ignore")
    folder = tempfile.mkdtemp()
    path = os.path.join(folder, "mine.toml")
    write_design(path, prototype().with_(R_mm=2.5, name="mine"))
    spec = CaptureSpec(scene="train", width=24, height=18, spp=4, design=path,
                       diffraction="auto", relative_illumination="cos4")  # fmt: skip
    calls = []

    def watch(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not module.startswith("pacam_render"):
            return
        code = frame.f_code
        names = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        if any(type(frame.f_locals.get(n)).__name__ in tracked for n in names):
            caller = frame.f_back.f_globals.get("__name__", "") if frame.f_back else ""
            calls.append((module, caller, code.co_name))

    sys.setprofile(watch)
    try:
        render_capture(spec, partial_dir=os.path.join(folder, "out", ".partial"), progress=False)
    finally:
        sys.setprofile(None)
    rank = {name: i for i, name in enumerate(LAYERS)}
    modules = collections.Counter(m for m, _, _ in calls)
    enters = collections.Counter(
        _floor(m) for m, c, _ in calls if not c.startswith("pacam_render") or _floor(c) != _floor(m)
    )
    climbs = [
        (c, m, f)
        for m, c, f in calls
        if c.startswith("pacam_render") and rank.get(_floor(m), 0) > rank.get(_floor(c), 0)
    ]
    print(f"{len(calls)} calls take the spec or its plan, in {len(modules)} modules")
    print("entries by subpackage: " + ", ".join(f"{k} {v}" for k, v in enters.most_common()))
    print(f"climbs (a lower subpackage calling a higher one): {len(climbs)}")
    for c, m, f in climbs:
        print(f"  {c} -> {m}.{f}")
    for m, n in sorted(modules.items()):
        print(f"  {n:3d} {m}")


if __name__ == "__main__":
    main()
