"""Which cell grid (issue 58): the rasterisation error of G x G cells, resolved on shared samples.

The reference is the prototype's disc on the LCoS's own pixels (1280 x 1024, each pixel open
whose centre lies in the disc: a bitmap design file, ``cell_design.fine_disc_design_spec``),
synthesised from a light-field store. Each grid G composes, from the same store's cell basis,
the disc rasterised on its cells (``cell_design.disc_code``). Both sum the very same samples,
weights differing only where a sample's LCoS pixel lies in a cell the disc's rim cuts, so their
difference is the rasterisation's, with only those samples' noise: its Monte Carlo sigma
(``diff sigma``) is measured from the spread of the passes' paired differences
(``synthesis.paired_difference``, the rasterised code written as its own design file).

Columns: ``rms diff / capture rms`` and ``/ capture MC sigma`` (the capture's own per-pixel
noise, rms over the window, from the store's passes), ``rms diff / diff sigma`` (>> 1: the
difference is resolved, not noise), ``raster rms`` (the difference's rms with its noise taken
out, sqrt(rms diff^2 - rms diff sigma^2): the rasterisation's own error), ``mean diff`` (the
light the rasterisation gains or loses: a window mean, nearly noise-free; ``open px`` is its
geometric cause, the open LCoS pixels summed over the patterns, no samples at all), ``raster
rms / sensor sigma`` (against the capture's reference sensor noise, its record's
``optics_error.reference_noise``: a synthesised capture's render noise is held under 0.3 of
it, ``synthesis.RENDER_NOISE_SHARE``, and the rasterisation is measured against the same bar),
the basis's memory (its arrays; the estimate the CLI
checks) and build seconds (one pass over the store), and a composition's milliseconds.

A second table checks that the fine bitmap is the disc: direct renders (``render_capture``) of
the disc design and of the fine bitmap design file with the same seed, and of the disc with
another seed for the renders' own noise: ``rms(bitmap - disc) / rms(disc seed a - seed b)``
near or under 1 means within Monte Carlo (the same seed shares most of its noise, so under).

    python benchmarks/bench_cell_grid.py [--quick]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np
from common import record

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.plan import plan_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.lightfield import StoreSpec, render_lightfield, synthesize
from pacam_render.lightfield.cell_basis import CELL_CHOICES, cell_basis, estimate_bytes
from pacam_render.lightfield.synthesis import paired_difference
from pacam_render.model.design_file import read_design
from pacam_render.optimize.cell_design import bitmap_design_spec, disc_code, fine_disc_design_spec

CROP = (440, 400, 64, 48)


def _spec(spp: int, passes: int, seed: int) -> CaptureSpec:
    return CaptureSpec.geometric(scene="train", width=1280, height=960, crop=CROP, mode="coded",
                                 grey=True, spp=spp, passes=passes, seed=seed)  # fmt: skip


def _rms(a) -> float:
    return float(np.sqrt(np.mean(np.square(a, dtype=np.float64))))


def grid_rows(store, spec, fine, fine_spec, grids, tmp: Path) -> list[dict]:
    """One row per grid G (module docstring) against ``fine``, the fine bitmap's capture."""
    plan = plan_capture(spec)
    sigma = fine.record.render_error.mc_sigma
    sensor = fine.record.optics_error["reference_noise"]["sigma"]
    fine_px = float(read_design(fine_spec.design).pattern_masks.array.sum(dtype=np.float64))
    rows = []
    for g in grids:
        t0 = time.perf_counter()
        basis = cell_basis(store, spec, g)
        build_s = time.perf_counter() - t0
        code = disc_code(plan, g)
        t0 = time.perf_counter()
        comp = basis.compose(code)[..., 0] if fine.image.ndim == 2 else basis.compose(code)
        compose_ms = 1e3 * (time.perf_counter() - t0)
        cells_spec = bitmap_design_spec(spec, basis, code, tmp / f"cells{g}.toml")
        diff, diff_sigma = paired_difference(store, cells_spec, fine_spec)
        assert np.abs(diff - (comp - fine.image)).max() <= 1e-4 * np.abs(fine.image).max()
        d = comp - fine.image
        _, _, w, h = store.manifest.camera.window
        rows.append({
            "G": g, "cells on lens": len(basis.cells_ij), "rms diff / capture rms":
            _rms(d) / _rms(fine.image), "rms diff / capture MC sigma": _rms(d) / sigma,
            "rms diff / diff sigma": _rms(d) / _rms(diff_sigma),
            "raster rms / capture rms": np.sqrt(max(_rms(d) ** 2 - _rms(diff_sigma) ** 2, 0.0))
            / _rms(fine.image),
            "raster rms / sensor sigma": np.sqrt(max(_rms(d) ** 2 - _rms(diff_sigma) ** 2, 0.0))
            / sensor,
            "mean diff / capture mean": float(np.mean(d) / np.mean(fine.image)),
            "open px: cells / fine - 1": float(basis.masks(code).sum(dtype=np.float64)) / fine_px
            - 1.0,
            "basis MiB": (basis.images.nbytes + basis.full.nbytes) / 2**20,
            "estimate MiB": estimate_bytes(basis.n_patterns, len(basis.cells_ij), h, w,
                                           store.manifest.channels) / 2**20,
            "build s": build_s, "compose ms": compose_ms,
        })  # fmt: skip
        del basis
    return rows


def direct_rows(spec, fine_spec) -> list[dict]:
    """The fine bitmap against the disc, direct renders (module docstring)."""
    disc = render_capture(spec, progress=False).image
    bitmap = render_capture(fine_spec, progress=False).image
    other = render_capture(dataclasses.replace(spec, seed=spec.seed + 1), progress=False).image
    mc = _rms(disc - other)
    return [{
        "spp": spec.spp, "rms(bitmap - disc), same seed": _rms(bitmap - disc),
        "rms(disc seed a - seed b)": mc, "ratio": _rms(bitmap - disc) / mc,
        "mean(bitmap - disc) / mean(disc)": float(np.mean(bitmap - disc) / np.mean(disc)),
    }]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="spp 64, grids 8 and 16")
    args = ap.parse_args()
    spp, direct_spp = (64, 64) if args.quick else (1024, 1024)
    grids = (8, 16) if args.quick else CELL_CHOICES
    spec = _spec(spp, 4, seed=5)
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        t0 = time.perf_counter()
        store = render_lightfield(StoreSpec(spec, alpha=1.0), tmp / "store", progress=False)
        store_s = time.perf_counter() - t0
        fine_spec = fine_disc_design_spec(spec, tmp / "fine.toml")
        fine = synthesize(store, fine_spec, progress=False)
        rows = grid_rows(store, spec, fine, fine_spec, grids, tmp)
        ref = fine.record.optics_error["reference_noise"]
        drows = direct_rows(_spec(direct_spp, 2, seed=11), fine_disc_design_spec(
            _spec(direct_spp, 2, seed=11), tmp / "fine_direct.toml"))  # fmt: skip
    notes = (
        f"train, window {CROP[2]}x{CROP[3]} at ({CROP[0]}, {CROP[1]}), grey, the prototype's "
        f"16-pattern disc schedule; store spp {spp} in 4 passes, alpha 1 ({store_s:.0f} s). "
        "Reference: the disc on the LCoS's own pixels as a bitmap design file, synthesised from "
        "the same store; each G composes the disc rasterised on its cells from the basis: the "
        "same samples, so the difference is the rasterisation's (diff sigma: the passes' paired "
        f"differences). Sensor sigma: {ref['sensor']}, {ref['sigma']:.3g} (capture units)."
    )
    record("Cell grid: rasterisation error against the disc on the LCoS pixels", rows, notes)
    record("Cell grid: the fine bitmap is the disc (direct renders)", drows,
           f"direct render_capture of the disc design and of its fine bitmap design file, "
           f"seed 11, spp {direct_spp} in 2 passes, same window; the disc with seed 12 for the "
           "renders' own noise.")  # fmt: skip


if __name__ == "__main__":
    main()
