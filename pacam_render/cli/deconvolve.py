"""``pacam deconvolve``: deblur a capture with one PSF, write the result and score it."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from ..capture.files import check_layers_fit, read_record
from ..capture.record import layer_unit
from ..errors import ParameterError
from ..exposure.deblur_psf import CapturePSF, load_capture_psf, psf_path
from ..io.exr import pick_layer, read_exr, read_layer_shapes, write_exr
from ..io.outputs import check_writable, prepare_out_dir, write_json
from ..io.preview import srgb8, write_png
from ..limits import PacamWarning, gib, note
from ..restore.capture_noise import check_noise_sigma, deblur_layer, sparse_options
from ..restore.deconvolve import (
    BM3D_LICENCE,
    METHODS,
    require_method,
)
from ..restore.deconvolve_cost import check_deconvolve
from ..restore.model_error import capture_model_sigma
from ..restore.restoration import restore_capture
from .common import add_force, add_out

_FILE_SUFFIXES = {".txt", ".json", ".npy", ".tif", ".tiff", ".jpg", ".jpeg", ".hdr", ".pfm"}
"""An --out with one of these is a mistyped file name, not a folder."""


def add(sub) -> None:
    p = sub.add_parser("deconvolve", help="deblur a capture with one PSF")
    p.add_argument("capture", metavar="CAPTURE.exr", help="the capture's EXR, or its folder")
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
        help="the whole noise std told the deconvolver, in the layer's units (default: the "
        "sensor's, recorded in the capture's JSON, for the noisy layer, plus the render's Monte "
        "Carlo sigma; otherwise estimated)",
    )
    p.add_argument(
        "--model-sigma",
        type=float,
        metavar="S",
        help="a model error (white = 1) to tell the deconvolver besides the sensor's and the "
        "render's noise: the capture's departure from the convolution model, calibrated on "
        "another capture of the same camera (default: none)",
    )
    p.add_argument(
        "--model-sigma-from",
        metavar="CAL.exr",
        help="measure that model error on another capture of the same camera, from its own "
        "truth layers (a calibration capture), and tell the deconvolver it",
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
    capture = capture / "capture.exr" if capture.is_dir() else capture  # a capture's folder
    psf_file = psf_path(args.psf, capture)
    inputs = [capture] if psf_file is None else [capture, psf_file]
    out, single_file = _deconvolve_out(args, inputs)  # before reading: a slip costs nothing
    shapes = read_layer_shapes(capture)  # the header only: the cost is checked before the pixels
    cost = _cost_before_reading(args, capture, psf_file, shapes)
    layers = read_exr(capture)
    layer = deblur_layer(list(layers), args.layer)
    image = pick_layer(layers, layer, capture)
    check_noise_sigma(args.noise_sigma, image)
    record = read_record(capture, required=psf_file is None)
    check_layers_fit(layers, record, capture, capture.with_suffix(".json"))
    model = _model_sigma(args)
    psf = load_capture_psf(args.psf, capture, record, args.allow_psf_mismatch)
    if args.method == "bm3d":
        print(f"note: {BM3D_LICENCE}", file=sys.stderr)
    costs = [cost]

    def check(kw: dict) -> None:  # an input the checks above refuse came first; still before
        if costs[0] is None:
            costs[0] = _check_cost(shapes, layer, psf.kernel.shape, args.method, kw)

    try:
        res = restore_capture({**layers, layer: image}, record, psf, args.method, layer,
                              args.colour, args.noise_sigma, model, before=check)  # fmt: skip
    except MemoryError:  # the estimate fitted, the machine's memory did not: one line
        raise MemoryError(
            f"deblurring layer {layer} with --method {args.method} ({costs[0].describe()} "
            f"estimated, {gib(costs[0].free)} available when it began); free memory, or use a "
            "method that needs less (wiener)"
        ) from None
    est, noise, how, seconds, sc = res.estimate, res.noise, res.how, res.seconds, res.score
    if noise["source"] == "noise_sigma":
        noise["source"] = "--noise-sigma"
    if single_file:
        _write_deconvolved_file(out, est, args.force)
    else:
        info = {"capture": str(capture), "layer": layer, "method": args.method, "seconds": seconds}
        info["flat_fielded"] = bool(noise.get("flat_field"))  # by its relative_illumination
        _write_deconvolved(out, est, record, {**info, **_psf_json(args, psf), **sc}, noise)
    print(
        f"wrote {out} ({args.method}, layer {layer}, noise {_noise_words(noise, how)}, "
        f"PSF {psf.kernel.shape[0]}x{psf.kernel.shape[1]} px from {args.psf}, {seconds:.2g} s)"
    )
    if sc:
        print(_score_line(sc))
    return 0


def _model_sigma(args: argparse.Namespace) -> float | None:
    """--model-sigma, or the model error measured on --model-sigma-from's capture
    (:func:`~pacam_render.restore.model_error.capture_model_sigma`); None for neither."""
    if args.model_sigma is not None and args.model_sigma_from is not None:
        raise ParameterError("give --model-sigma or --model-sigma-from, not both")
    if args.noise_sigma is not None and (args.model_sigma, args.model_sigma_from) != (None, None):
        raise ParameterError(
            "--noise-sigma is the whole noise told the deconvolver: give --model-sigma "
            "(or --model-sigma-from) without it"
        )
    if args.model_sigma is not None:
        return check_model_sigma(args.model_sigma)
    if args.model_sigma_from is None:
        return None

    cal = Path(args.model_sigma_from)
    cal = cal / "capture.exr" if cal.is_dir() else cal
    layers, record = read_exr(cal), read_record(cal)
    missing = {"capture", "sharp", "object_id", "velocity"} - set(layers)
    if missing:
        raise ParameterError(
            f"--model-sigma-from {cal}: a calibration capture needs its truth layers; it lacks "
            f"{', '.join(sorted(missing))} (render it without --no-truth)"
        )
    return capture_model_sigma(layers, record)


def check_model_sigma(value: float) -> float:
    """A model sigma in [0, 10] (white = 1), or a ParameterError naming --model-sigma."""
    if not 0.0 <= float(value) <= 10.0:  # also NaN
        raise ParameterError(f"--model-sigma must be in [0, 10] (white = 1), got {value!r}")
    return float(value)


NOTE_SECONDS = 10.0
"""A deconvolution estimated to take longer says so, with its memory, before it starts."""


def _cost_before_reading(args: argparse.Namespace, capture: Path, psf_file, shapes: dict):
    """:func:`_check_cost` from the EXR's header, the record and the PSF, before any pixel is
    read; None when one of them has an error, which the command then reports where it checks
    it (after reading, as ever), the cost checked after it."""
    try:
        layer = deblur_layer(list(shapes), args.layer)
        if layer not in shapes:
            return None
        record = read_record(capture, required=psf_file is None)
        kw, _ = sparse_options(args.method, layer, record, args.colour, args.noise_sigma)
        with warnings.catch_warnings():  # its notes are said once, when the command loads it
            warnings.simplefilter("ignore", PacamWarning)
            psf = load_capture_psf(args.psf, capture, record, args.allow_psf_mismatch)
    except ParameterError:
        return None
    return _check_cost(shapes, layer, psf.kernel.shape, args.method, kw)


def _check_cost(shapes: dict, layer: str, psf_shape, method: str, kw: dict):
    """The deconvolution's estimated memory and seconds
    (:mod:`~pacam_render.restore.deconvolve_cost`), from the EXR's header, before its pixels are
    read: refused when the memory is not available (every layer is read, as float32, besides the
    method's arrays), noted when long."""
    shape = shapes[layer]
    channels = shape[2] if len(shape) == 3 else 1
    read = 4.0 * sum(float(np.prod(s)) for s in shapes.values())
    copies = 2 * 8.0 * shape[0] * shape[1] * channels  # a flat-field or clip; the registration
    cost = check_deconvolve(shape, psf_shape, method, kw, read + copies)
    if cost.seconds >= NOTE_SECONDS:
        note(
            f"deblurring layer {layer} ({shape[1]}x{shape[0]} px, {channels} channel(s)) with "
            f"`method` {method} takes {cost.describe()} (estimated; {gib(cost.free)} "
            "available)"
        )
    return cost


def _deconvolve_out(args: argparse.Namespace, inputs: list[Path]) -> tuple[Path, bool]:
    """The output folder, or (``file`` True) the single .exr/.png file of older versions;
    refused if it would replace an input or, without --force, an existing result."""
    out = Path(args.out)
    if any(out.resolve() == p.resolve() for p in inputs):
        raise ParameterError(f"--out {out} is an input of this command; give another path")
    if out.suffix in (".exr", ".png"):
        if args.allow_psf_mismatch:
            raise ParameterError(
                f"--allow-psf-mismatch needs --out DIR: --out {out} writes the image only, "
                "so the mismatch it allows would be recorded nowhere (DIR's deconvolved.json "
                "records it)"
            )
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

    lf = None if record is None else record.light_factor
    exposure = 1.0 / lf if lf else None
    meta = {
        **info,
        "noise_sigma": noise["sigma"],
        "noise_sigma_source": noise["source"],
        "render_noise_sigma": noise.get("render_sigma", 0.0),
        "model_sigma": noise.get("model_sigma", 0.0),
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
