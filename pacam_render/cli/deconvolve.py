"""``pacam deconvolve``: deblur a capture with one PSF, write the result and score it."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from ..exposure.capture_psf import CapturePSF, load_capture_psf, psf_path
from ..exposure.record import read_record
from ..io.exr import pick_layer, read_exr, write_exr
from ..io.outputs import check_writable, prepare_out_dir, write_json
from ..io.preview import srgb8, write_png
from ..psf.origin import to_pinhole
from ..restore.capture_noise import check_noise_sigma, deblur_layer, deblur_noise, sparse_options
from ..restore.deconvolve import BM3D_LICENCE, METHODS, deconvolve, require_method
from .common import add_force, add_out

_FILE_SUFFIXES = {".txt", ".json", ".npy", ".tif", ".tiff", ".jpg", ".jpeg", ".hdr", ".pfm"}
"""An --out with one of these is a mistyped file name, not a folder."""


def add(sub) -> None:
    p = sub.add_parser("deconvolve", help="deblur a capture with one PSF")
    p.add_argument("capture", metavar="CAPTURE.exr")
    p.add_argument(
        "--psf",
        default="analytic",
        help="analytic (s = 0) | robust (the analytic PSF averaged over the design's speed "
        "range: better at its edge, worse at rest) | rendered | PATH (.exr or .npy)",
    )
    p.add_argument(
        "--method",
        default="hl",
        choices=METHODS,
        help="default hl (hyper-Laplacian prior); pnp (a CNN prior) is optional: pip install "
        f"'pacam_render[pnp]'; bm3d is optional: pip install bm3d ({BM3D_LICENCE})",
    )
    p.add_argument(
        "--colour",
        choices=("joint", "channel"),
        help="hl/tv: one prior on each gradient's colour vector, or one per channel (default: "
        "joint for hl, channel for tv, the better of each)",
    )

    p.add_argument(
        "--layer",
        help="EXR layer to deconvolve (default: noisy when the capture has one, else capture)",
    )
    p.add_argument(
        "--noise-sigma",
        type=float,
        help="noise std in the layer's units (default: the sensor's, recorded in the capture's "
        "JSON, for the noisy layer; otherwise estimated)",
    )
    p.add_argument(
        "--allow-psf-mismatch",
        action="store_true",
        help="deblur with a PSF file made for another camera (r, a_i, pattern count, depth, "
        "...) on purpose, e.g. a wrong assumed depth as in the paper's Fig. 9; without it such "
        "a file is refused",
    )
    add_out(
        p,
        help="folder for deconvolved.exr, .png and .json (method, PSF, noise, seconds and the "
        "score against sharp); a path ending in .exr or .png writes that one file, as before",
    )
    add_force(p, "overwrite existing results")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    require_method(args.method)  # an optional package missing: said before reading anything
    capture = Path(args.capture)
    psf_file = psf_path(args.psf, capture)
    inputs = [capture] if psf_file is None else [capture, psf_file]
    out, single_file = _deconvolve_out(args, inputs)  # before reading: a slip costs nothing
    layers = read_exr(capture)
    layer = deblur_layer(list(layers), args.layer)
    image = pick_layer(layers, layer, capture)
    check_noise_sigma(args.noise_sigma, image)
    record = read_record(capture, required=psf_file is None)
    kw, how = sparse_options(args.method, layer, record, args.colour, args.noise_sigma)
    psf = load_capture_psf(args.psf, capture, record, args.allow_psf_mismatch)
    noise = deblur_noise(args.method, kw, how, image, layer, layers, record, args.noise_sigma)
    if noise["source"] == "noise_sigma":
        noise["source"] = "--noise-sigma"
    if args.method == "bm3d":
        print(f"note: {BM3D_LICENCE}", file=sys.stderr)
    start = time.perf_counter()
    est = deconvolve(image, psf.kernel, args.method, **kw)
    est = to_pinhole(est, psf.origin, psf.t0_offset_px)  # the capture's registration
    seconds = time.perf_counter() - start
    sc = _deconvolve_score(est, layers, layer, record)
    if single_file:
        _write_deconvolved_file(out, est, args.force)
    else:
        info = {"capture": str(capture), "layer": layer, "method": args.method, "seconds": seconds}
        _write_deconvolved(out, est, record, {**info, **_psf_json(args, psf), **sc}, noise)
    print(
        f"wrote {out} ({args.method}, layer {layer}, noise {_noise_words(noise, how)}, "
        f"PSF {psf.kernel.shape[0]}x{psf.kernel.shape[1]} px from {args.psf}, {seconds:.2g} s)"
    )
    if sc:
        print(_score_line(sc))
    return 0


def _deconvolve_out(args: argparse.Namespace, inputs: list[Path]) -> tuple[Path, bool]:
    """The output folder, or (``file`` True) the single .exr/.png file of older versions;
    refused if it would replace an input or, without --force, an existing result."""
    out = Path(args.out)
    if any(out.resolve() == p.resolve() for p in inputs):
        raise ParameterError(f"--out {out} is an input of this command; give another path")
    if out.suffix in (".exr", ".png"):
        print(
            f"note: --out {out} writes the image only; --out DIR writes deconvolved.exr, "
            ".png and .json (method, PSF, noise and the score against sharp)",
            file=sys.stderr,
        )
        return check_writable(out, args.force, "--out"), True
    if out.suffix.lower() in _FILE_SUFFIXES and not out.is_dir():
        raise ParameterError(
            f"--out {out} names a file; give a folder (or a file ending in .exr or .png)"
        )
    return prepare_out_dir(out, args.force), False


def _deconvolve_score(est, layers: dict, layer: str, record) -> dict:
    """PSNR and SSIM against ``sharp`` as a study scores (:func:`.study.score.score_capture`),
    on the white scale; empty without the truth layers (``--no-truth``) or for a layer that is
    not the image."""
    from ..study.score import score_capture

    truth = {"sharp", "object_id", "velocity"}
    if record is None or layer not in ("capture", "noisy") or not truth <= set(layers):
        return {}
    if record.light_factor <= 0 or est.shape != layers["sharp"].shape:
        return {}
    out = score_capture(est / record.light_factor, layers, record)
    return {**out, "psnr_by_object": json.loads(out["psnr_by_object"])}


def _score_line(sc: dict) -> str:
    moving = sc["psnr_moving_db"]
    still = f"still {sc['psnr_static_db']:.2f} dB" + (
        f", moving {moving:.2f} dB (each at its best shift)" if np.isfinite(moving) else ""
    )
    return f"score against sharp: PSNR {sc['psnr_db']:.2f} dB, SSIM {sc['ssim']:.3f}; {still}"


def _noise_words(noise: dict, model: str | None) -> str:
    """The noise for the summary line: the sensor's model, a sigma and its source, or not
    used."""
    sigma = noise["sigma"]
    if model is not None or sigma is None:
        return model or noise["source"]
    if noise["source"].startswith("estimated"):
        return f"estimated, sigma {sigma:.4g}"
    return f"sigma {sigma:.4g} ({noise['source']})"


def _psf_json(args, psf: CapturePSF) -> dict:
    """The PSF's entry in deconvolved.json."""
    shift = -psf.t0_offset_px if psf.origin == "t0" else 0.0
    return {
        "psf": {
            "source": args.psf,
            "file": None if psf.file is None else str(psf.file),
            "size_px": list(psf.kernel.shape[:2]),
            "origin": psf.origin,
            "result_shifted_px": shift,  # onto the pinhole image, the capture's registration
            **({"mismatch": list(psf.mismatch)} if psf.mismatch else {}),
        }
    }


def _write_deconvolved_file(out: Path, est, force: bool) -> None:
    if out.suffix == ".exr":
        write_exr(out, {"deconvolved": est}, force=force)
    else:
        write_png(out, srgb8(est), force=force)


def _write_deconvolved(out: Path, est, record, info: dict, noise: dict) -> None:
    """deconvolved.exr (the layer's units), .png (exposed like capture.png) and .json."""
    from ..exposure.record import layer_unit

    lf = None if record is None else record.light_factor
    exposure = 1.0 / lf if lf else None
    meta = {
        **info,
        "noise_sigma": noise["sigma"],
        "noise_sigma_source": noise["source"],
        "light_factor": lf,
        "units": {"deconvolved": layer_unit(info["layer"])},
    }
    if "psnr_db" in info:
        meta["score_note"] = (
            "against the capture's sharp layer, deconvolved / light_factor, as pacam study "
            "scores (PSNR and SSIM over the window; per object PSNR dB and best shift px)"
        )
    write_exr(out / "deconvolved.exr", {"deconvolved": est}, force=True)
    write_png(out / "deconvolved.png", srgb8(est, exposure), force=True)
    write_json(out / "deconvolved.json", meta, force=True)
