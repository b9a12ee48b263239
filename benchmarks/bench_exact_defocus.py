"""The exact defocused PSF in the rays against the disc-plus-Airy draw it replaced: time, and
the error, side by side at equal samples (issue 45, item 6).

**Particles** (``--only particles``).
For the prototype (r = 2 px, 0.60 waves) and ``--cover 1.4`` (r = 3.13 px, 0.93 waves), grey at
550 nm, a static coded PSF is rendered by ``pacam psf --render --diffraction on`` with each
draw, two seeds each. The error is the L1 distance to the exact analytic kernel (itself within
0.0004 of an independent Fresnel computation, tests/render/test_exact_defocus.py); the Monte
Carlo floor is the L1 between the two seeds' kernels over sqrt(2).

**Camera rays** (``--only paths``). The path tracer's exact rays probe the scene for the depth
they meet (one more intersection per camera ray, :mod:`pacam_render.render.kernels.defocus_draw`).
The cost: a coded capture of the train (256 x 192 window, 512 spp, RGB, diffraction on) with the
exact rays, with the Airy draw, and geometric (diffraction off), each rendered twice with two
seeds after a warm-up; seconds per render, and the Monte Carlo variance at equal samples (the
two seeds' mean squared difference / 2) over the geometric render's. The error: a 5-degree
edge at r = 2 px (0.6 waves), its green MTF against the exact defocused OTF (an independent
Fresnel FFT, as tests/render/test_exact_defocus.py), max over 0.05-0.45 cycles/px, at 256 and
1024 spp.

    python benchmarks/bench_exact_defocus.py [--only particles|paths]
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
    from pacam_render.render.kernels.defocus_draw import ExactDefocus

    ac.ProgrammableApertureCamera._exact_defocus_on = (
        ExactDefocus._exact_defocus_on if exact else (lambda self: False)
    )


def particles() -> None:
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


def _rays(mode: str) -> None:
    """Choose the camera rays' diffraction: exact, airy (the draw before) or as shipped."""
    from pacam_render.render import aperture_camera as ac
    from pacam_render.render.kernels.defocus_draw import ExactDefocus

    ac.ProgrammableApertureCamera._exact_ray_on = (
        (lambda self: False) if mode == "airy" else ExactDefocus._exact_ray_on
    )


def _train(diffraction: str, seed: int) -> tuple[np.ndarray, float]:
    from pacam_render.exposure.direct import render_capture
    from pacam_render.exposure.spec import CaptureSpec

    spec = CaptureSpec.geometric(scene="train", mode="coded", width=1280, height=960,
                       crop=(384, 544, 256, 192), spp=512,
                       diffraction=diffraction, seed=seed)  # fmt: skip
    t0 = time.perf_counter()
    cap = render_capture(spec, progress=False, truth=False)
    return np.asarray(cap.image, float), time.perf_counter() - t0


def _edge_error(spp: int) -> float:
    """Max |MTF - exact OTF| of the r = 2 px edge (green, 0.05-0.45 cycles/px)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from pacam_render.wave.edge_mtf import edge_mtf, fit_edge
    from tests.render.test_exact_defocus import _defocused_edge, fresnel_otf

    nu, r = np.linspace(0.05, 0.45, 9), 2.0
    cap, lam_n = _defocused_edge(r, spp, diffraction="on")
    otf, grid = fresnel_otf(0.5 * np.pi * r / lam_n, lam_n)
    o = np.argsort(grid)
    tilt = np.radians(5.0)
    pixel = np.sinc(nu * np.cos(tilt)) * np.sinc(nu * np.sin(tilt))
    exact = np.interp(nu, grid[o], otf[0].real[o]) * pixel
    green = cap.image[..., 1]
    got = edge_mtf(green, *fit_edge(green), nu, 15.0, contrast=cap.record.light_factor)
    return float(np.max(np.abs(got - exact)))


def paths() -> None:
    import warnings

    from pacam_render.render import register
    from pacam_render.render.backend import select_variant

    warnings.simplefilter("ignore")
    select_variant(mono=False)  # the variant RGB captures render in
    register()
    rows = []
    runs = {}
    for label, diffraction, rays in (("geometric (off)", "off", "exact"),
                                     ("disc + Airy", "on", "airy"),
                                     ("exact (probe)", "on", "exact")):  # fmt: skip
        _rays(rays)
        _train(diffraction, 9)  # warm-up: the kernels' compilation
        runs[label] = [_train(diffraction, s) for s in (0, 1)]
    base = None
    for label, ((a, ta), (b, tb)) in runs.items():
        var = float(np.mean((a - b) ** 2)) / 2.0
        sec = 0.5 * (ta + tb)
        base = base or (sec, var)
        rows.append({"rays": label, "s / render": round(sec, 2),
                     "time / geometric": round(sec / base[0], 3),
                     "MC variance / geometric": round(var / base[1], 3),
                     "edge MTF max error": "-"})  # fmt: skip
    for spp in (256, 1024):
        for label, rays in (("disc + Airy", "airy"), ("exact (probe)", "exact")):
            _rays(rays)
            t0 = time.perf_counter()
            err = _edge_error(spp)
            rows.append({"rays": f"{label}, edge at {spp} spp",
                         "s / render": round(time.perf_counter() - t0, 2),
                         "time / geometric": "-", "MC variance / geometric": "-",
                         "edge MTF max error": round(err, 4)})  # fmt: skip
    _rays("exact")
    record(
        "Exact defocused PSF in the camera rays (path tracing): cost and error",
        rows,
        "train, coded, 256x192 window, 512 spp RGB, two seeds after a warm-up; MC variance at "
        "equal samples = the seeds' mean squared difference / 2. Edge: r = 2 px, green MTF max "
        "|error| to the exact defocused OTF over 0.05-0.45 cycles/px (independent Fresnel FFT)",
    )


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("particles", "paths"))
    only = ap.parse_args().only
    if only in (None, "particles"):
        particles()
    if only in (None, "paths"):
        paths()
