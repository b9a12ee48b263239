"""The particle tracer's exact defocused PSF against the disc-plus-Airy draw it replaced:
time, and the error of the rendered kernel, side by side at equal samples (issue 45, item 6).

For the prototype (r = 2 px, 0.60 waves) and ``--cover 1.4`` (r = 3.13 px, 0.93 waves), grey at
550 nm, a static coded PSF is rendered by ``pacam psf --render --diffraction on`` with each
draw, two seeds each. The error is the L1 distance to the exact analytic kernel (itself within
0.0004 of an independent Fresnel computation, tests/render/test_exact_defocus.py); the Monte
Carlo floor is the L1 between the two seeds' kernels over sqrt(2).

    python benchmarks/bench_exact_defocus.py
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np
from common import record

from pacam_render.cli import main
from pacam_render.io.exr import read_exr
from pacam_render.model.camera import CameraDesign
from pacam_render.psf.exact_defocus import exact_defocus_kernel

CASES = {"prototype (r = 2 px)": [], "cover 1.4 (r = 3.13 px)": ["--cover", "1.4"]}


def _render(out: Path, flags: list, seed: int) -> tuple[np.ndarray, float, dict]:
    args = ["psf", "--mode", "coded", "--depth", "500", "--velocity", "0", "--render",
            "--diffraction", "on", "--grey", "--spp", "1024", "--seed", str(seed), "--quiet",
            "--out", str(out), *flags]  # fmt: skip
    t0 = time.perf_counter()
    assert main(args) == 0
    seconds = time.perf_counter() - t0
    layers = read_exr(out / "psf_rendered.exr")
    k = np.asarray(next(iter(layers.values())) if isinstance(layers, dict) else layers, float)
    return k.squeeze() / k.sum(), seconds, json.loads((out / "psf.json").read_text())


def _draw(exact: bool) -> None:
    """Choose the particles' draw: the exact PSF, or the geometric lens point plus Airy."""
    from pacam_render.render import aperture_camera as ac
    from pacam_render.render.defocus_draw import ExactDefocus

    ac.ProgrammableApertureCamera._exact_defocus_on = (
        ExactDefocus._exact_defocus_on if exact else (lambda self: False)
    )


def main_() -> None:
    from pacam_render.render import register
    from pacam_render.render.backend import select_variant

    select_variant(mono=True)  # the variant --grey renders in: the plugin is imported once
    register()
    rows = []
    root = Path(tempfile.mkdtemp(prefix="bench_exact_defocus."))
    for name, flags in CASES.items():
        out = {}
        for exact in (False, True):
            _draw(exact)
            runs = [_render(root / f"{name[:5]}{exact}{s}", flags, s) for s in (0, 1)]
            out[exact] = runs
        _draw(True)
        meta = out[True][0][2]
        cam = CameraDesign.from_inputs(meta["camera"])
        shape = out[True][0][0].shape
        ref = exact_defocus_kernel(cam, "coded", 0.0, meta["origin"], 550.0, shape)
        for exact, label in ((False, "disc + Airy"), (True, "exact")):
            (k0, t0, _), (k1, t1, _) = out[exact]
            rows.append({
                "case": name, "draw": label, "seconds (2 renders)": round(t0 + t1, 2),
                "L1 to exact": round(float(np.abs(0.5 * (k0 + k1) - ref).sum()), 4),
                "MC floor L1": round(float(np.abs(k0 - k1).sum()) / 2.0, 4),
            })  # fmt: skip
    record(
        "Exact defocused PSF in the particle tracer: time and error at equal samples",
        rows,
        "static coded PSFs, grey 550 nm, 1024 spp (pacam psf --render --diffraction on), two "
        "seeds each; L1 of the seeds' mean to the exact analytic kernel; the floor is the "
        "seeds' L1 / 2 (the mean's own noise, about)",
    )


if __name__ == "__main__":
    main_()
