"""The ``pacam`` command line. Bad input prints one clear line and exits 2, never a traceback."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .errors import FileKeyError, ParameterError, check_finite, check_positive
from .exposure.capture import CaptureInterrupted
from .exposure.record import CaptureRecord, analytic_psf, robust_psf
from .io.exr import pick_layer, read_exr, write_exr
from .io.outputs import check_writable, prepare_out_dir, writable_dir, write_json
from .io.preview import srgb8, write_png
from .limits import DEFAULT_MAX_SAMPLES, DEFAULT_MAX_STEPS, PacamWarning
from .model.camera import CameraDesign, preset, prototype
from .model.design import solve
from .model.modes import MODES, MODES_WITH_PSF
from .model.report import design_report
from .psf.analytic import design_psf
from .psf.origin import origin_record, to_pinhole
from .render.samplers import DEFAULT_SAMPLER, SAMPLERS
from .restore.deconvolve import BM3D_LICENCE, METHODS, deconvolve
from .sensor.apply import layer_noise


def _design_from_args(args: argparse.Namespace) -> CameraDesign:
    for flag, unit in (("depth", "mm"), ("exposure", "ms"), ("max_velocity", "px/ms")):
        if getattr(args, flag) is not None:
            check_positive("--" + flag.replace("_", "-"), getattr(args, flag), unit)
    depth = {} if args.depth is None else {"object_depth_mm": args.depth}
    base = preset(args.preset, **depth)
    if args.max_velocity is None:
        if args.f_number is not None or args.r_px is not None:
            raise ParameterError("--f-number and --r-px need --max-velocity (the speed to cover)")
        if args.exposure is not None:
            base = base.with_(exposure_ms=args.exposure)
        return base
    return solve(
        args.max_velocity,
        exposure_ms=args.exposure,
        object_depth_mm=args.depth,
        f_number=args.f_number,
        r_px=args.r_px,
        base=base,
    )


def _cmd_design(args: argparse.Namespace) -> int:
    d = _design_from_args(args)
    if args.json:
        print(json.dumps(d.summary(), indent=2))
    else:
        print(design_report(d))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .experiments.demo import check_size, run_demo
    from .io.lock import output_lock

    check_size(args.width, args.height, args.spp)
    out = prepare_out_dir(args.out, args.force)
    print(design_report(prototype()))
    where = (
        "a window of the full 1280x960 sensor"
        if args.width is None and args.height is None
        else f"a binned {args.width or 1280}x{args.height or 960} sensor"
    )
    print(f"\nrendering the train set ({where}, {args.spp} spp) ...")
    with output_lock(out):
        fig = run_demo(out, args.width, args.height, args.spp, args.force)
    print((fig.parent / "demo.md").read_text())
    print(f"figure: {fig}")
    return 0


def _cmd_psf(args: argparse.Namespace) -> int:
    if args.origin is None:  # a kernel made for a capture is centred as deconvolve centres it
        args.origin = "pinhole" if args.like is not None else "t0"
    check_positive("--depth", args.depth, "mm")
    check_finite("--velocity", args.velocity)
    cam, crop = _psf_geometry(args)
    cam = cam.with_(object_depth_mm=args.depth)
    if args.size is not None:
        _odd_size(args.size)
    seed = 0 if args.seed is None else args.seed
    if args.render:  # check everything before computing or writing anything
        from .exposure.psf_render import check_request

        check_request(cam, args.spp, seed, args.film)
        check_positive("--max-samples", args.max_samples)
    elif args.spp is not None or args.seed is not None:
        raise ParameterError("--spp and --seed need --render")
    out = prepare_out_dir(args.out, args.force)
    k = _checked_psf(cam, args)
    r = _rendered_psf(cam, k, seed, args) if args.render else None
    # nothing is written before the render ends: an interrupt leaves no half set of files
    write_exr(out / "psf_analytic.exr", {"psf": k}, force=args.force)
    write_png(out / "psf_analytic.png", srgb8(k), force=args.force)
    meta = {
        **cam.summary(),
        "mode": args.mode,
        "velocity_px_per_ms": args.velocity,
        "size_px": list(k.shape),
        **({"crop": crop} if crop else {}),
        **origin_record(cam, args.mode, args.origin),
        "psf_origin": "centre pixel = where the point images at mid-exposure (t = 0)"
        if args.origin == "t0"
        else "centre pixel = where a pinhole at the lens centre images the point at t = 0",
    }
    written = "psf_analytic.exr, psf_analytic.png"
    if r is not None:
        from .restore.metrics import rel_l1

        write_exr(out / "psf_rendered.exr", {"psf": r.kernel}, force=args.force)
        write_png(out / "psf_rendered.png", srgb8(r.kernel), force=args.force)
        meta["rendered"] = {**r.to_json(), "l1_vs_analytic": rel_l1(r.kernel, k)}
        written += ", psf_rendered.exr, psf_rendered.png"
        print(
            f"rendered in {r.seconds:.1f} s ({r.particles} particles, spp {r.spp}, seed "
            f"{r.seed}): L1 to the analytic PSF {rel_l1(r.kernel, k):.4f}, fitted a_i "
            f"{r.fitted_a_i:.5g} px/ms^2 (Eq. 18: {r.model_a_i:.5g})"
        )
    write_json(out / "psf.json", meta, force=args.force)
    print(f"wrote {out}/: {written}, psf.json ({k.shape[0]}x{k.shape[1]} px)")
    return 0


def _rendered_psf(cam: CameraDesign, k: np.ndarray, seed: int, args: argparse.Namespace):
    """The ray-traced kernel; refused beyond --max-samples before any rendering."""
    from .exposure.psf_render import render_psf

    return render_psf(
        cam, args.mode, args.velocity, size=k.shape, spp=args.spp, seed=seed, film=args.film,
        origin=args.origin, model=k, max_samples=args.max_samples, progress=not args.quiet,
    )  # fmt: skip


def _psf_geometry(args: argparse.Namespace) -> tuple[CameraDesign, dict | None]:
    """The preset at the capture's sensor size (``--like``, or ``--width``/``--height``), and
    the crop to record. A kernel's px quantities (r, a_i) follow the sensor's size; a crop does
    not change the kernel, only where it applies."""
    base = preset(args.preset)
    if args.like is not None:
        if args.width or args.height or args.crop:
            raise ParameterError("--like copies the capture's size and crop: leave out --width, "
                                 "--height and --crop")  # fmt: skip
        capture = Path(args.like)
        record = _capture_record(capture, required=True)
        if record is None:
            raise ParameterError(f"--like needs the capture's {capture.with_suffix('.json')}")
        cam = record.camera
        return base.with_(width_px=cam["width_px"], height_px=cam["height_px"]), record.crop
    width = args.width or base.width_px
    height = args.height or base.height_px
    base = base.with_(width_px=width, height_px=height)
    if args.crop is None:
        return base, None
    from .exposure.capture import check_crop, parse_crop

    x, y, w, h = check_crop(parse_crop(args.crop), width, height)
    crop = {"x": x, "y": y, "width": w, "height": h}
    return base, {**crop, "sensor_width_px": width, "sensor_height_px": height}


def _checked_psf(cam: CameraDesign, args: argparse.Namespace) -> np.ndarray:
    """The analytic kernel, refused if more than MAX_LOST_FRACTION of it falls outside."""
    from .psf.analytic import MAX_LOST_FRACTION, PSFTruncationWarning, least_lost_fraction

    size = None if args.size is None else _odd_size(args.size)
    # a bound first: the kernel of a huge defocus takes minutes to compute, then is refused
    least, (h, w), r = least_lost_fraction(cam, args.mode, args.velocity, size, args.origin)
    if least > MAX_LOST_FRACTION:
        raise ParameterError(
            f"at least {least:.3%} of the PSF falls outside the {h}x{w} kernel (its defocus "
            f"radius is {r:.4g} px on a {cam.width_px}x{cam.height_px} px sensor), more than "
            f"the {MAX_LOST_FRACTION:.0%} allowed; lower --width/--height (px quantities grow "
            "with them) or give a larger --size (the automatic size stops at 2049 px)"
        )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PSFTruncationWarning)
        k = design_psf(cam, args.mode, args.velocity, size, origin=args.origin)
    lost = max((getattr(w.message, "lost", 0.0) for w in caught), default=0.0)
    if lost > MAX_LOST_FRACTION:
        raise ParameterError(
            f"{lost:.3%} of the PSF (--velocity {args.velocity:g} px/ms at --depth "
            f"{args.depth:g} mm) falls outside the {k.shape[0]}x{k.shape[1]} kernel, more than "
            f"the {MAX_LOST_FRACTION:.0%} allowed; give a larger --size (the automatic size "
            "stops at 2049 px) or a lower --velocity"
        )
    for w in caught:  # a small loss: one note
        warnings.warn(str(w.message), PacamWarning, stacklevel=2)
    return k


def _odd_size(n: int) -> int:
    if n < 1 or n % 2 == 0:
        raise ParameterError(f"--size must be a positive odd number of px, got {n}")
    return n


def _capture_record(capture: Path, required: bool) -> CaptureRecord | None:
    """The capture's record from its JSON sidecar, or None if it has none. Only ``--psf
    analytic`` needs the camera in it (``required``); otherwise an incomplete sidecar is read
    for nothing but its noise, with a note."""
    path = capture.with_suffix(".json")
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{path} is not valid JSON ({exc})") from exc
    try:
        return CaptureRecord.from_json(data, where=str(path))
    except ParameterError as exc:
        if required:
            raise
        print(f"note: {exc}; its noise sigma is not used", file=sys.stderr)
        return None


class _PSF(NamedTuple):
    """A kernel to deblur with, where it came from, and what its centre pixel stands for."""

    kernel: np.ndarray
    file: Path | None
    origin: str
    t0_offset_px: float


def _load_psf(spec: str, capture: Path, record: CaptureRecord | None) -> _PSF:
    if spec in ("analytic", "robust"):
        if record is None:
            path = capture.with_suffix(".json")
            raise ParameterError(f"--psf {spec} needs the capture's parameters in {path}")
        k = analytic_psf(record) if spec == "analytic" else robust_psf(record)
        return _PSF(k, None, "pinhole", 0.0)
    path = capture.parent / "psf_rendered.exr" if spec == "rendered" else Path(spec)
    if spec == "rendered" and not path.is_file():
        raise ParameterError(
            f"--psf rendered reads {path}, which does not exist; make it with `pacam psf "
            f"--render --out {capture.parent} ...` at the capture's depth and mode, or use "
            "--psf analytic"
        )
    meta = _psf_sidecar(path)
    _check_psf_scale(path, meta, capture, record)
    origin, offset = _psf_origin(path, meta)
    if path.suffix == ".npy":
        return _PSF(_load_npy_psf(path), path, origin, offset)
    layers = read_exr(path)
    if "psf" in layers:
        return _PSF(layers["psf"], path, origin, offset)
    if len(layers) == 1:
        return _PSF(next(iter(layers.values())), path, origin, offset)
    raise ParameterError(f"{path} has no 'psf' layer; it has: {', '.join(sorted(layers))}")


def _psf_sidecar(path: Path) -> dict | None:
    """The ``psf.json`` that ``pacam psf`` wrote beside an EXR kernel, or None."""
    sidecar = path.parent / "psf.json"
    if path.suffix == ".npy" or not sidecar.is_file():
        return None
    try:
        meta = json.loads(sidecar.read_text())
    except json.JSONDecodeError:
        return None
    return meta if isinstance(meta, dict) else None


def _psf_origin(path: Path, meta: dict | None) -> tuple[str, float]:
    """The kernel's origin and t = 0 offset (px) from its psf.json. A kernel without one is
    taken as centred like the capture (the pinhole image); an older t0 file, which lacks the
    offset, is used as it is, with a note."""
    from .psf.origin import recorded_origin

    origin, offset = recorded_origin(meta or {})
    if origin == "t0" and offset is None:
        warnings.warn(
            f"{path} is centred on the t = 0 image but its psf.json (from an older pacam) does "
            "not record how far that lies from the pinhole image, so the result is not moved "
            "onto the capture's registration; remake it with pacam psf --like CAPTURE.exr",
            PacamWarning,
            stacklevel=2,
        )
        return "pinhole", 0.0
    return origin or "pinhole", offset or 0.0


def _check_psf_scale(path: Path, meta, capture: Path, record: CaptureRecord | None) -> None:
    """Refuse a kernel made for another sensor size than the capture's (px scale differs)."""
    sidecar = path.parent / "psf.json"
    if not isinstance(meta, dict) or "width_px" not in meta:
        warnings.warn(
            f"{path} records no sensor size: make sure it was made at the capture's scale "
            f"(pacam psf --like {capture})",
            PacamWarning,
            stacklevel=2,
        )
        return
    if record is None or "width_px" not in record.camera:
        return
    made = (meta["width_px"], meta.get("height_px"))
    needed = (record.camera["width_px"], record.camera.get("height_px"))
    if made != needed:
        raise ParameterError(
            f"--psf {path} was made for a {made[0]}x{made[1]} sensor ({sidecar}), the capture "
            f"for {needed[0]}x{needed[1]}: its px are a different size; make the kernel with "
            f"pacam psf --like {capture} ..."
        )


def _load_npy_psf(path: Path) -> np.ndarray:
    """A kernel from a ``.npy`` file: numbers only (never unpickle a file from elsewhere)."""
    if not path.is_file():
        raise ParameterError(f"--psf file {path} does not exist")
    try:
        k = np.load(path, allow_pickle=False)
    except (ValueError, EOFError) as exc:  # object arrays, an empty file, or not a .npy file
        why = "holds Python objects" if "allow_pickle" in str(exc) else f"is not readable ({exc})"
        raise ParameterError(
            f"--psf file {path} {why}; save the kernel as numbers: "
            "np.save(path, np.asarray(kernel, dtype=float))"
        ) from None
    if not isinstance(k, np.ndarray) or k.dtype.kind not in "biuf":
        raise ParameterError(f"--psf file {path} holds {k.dtype} values, not real numbers")
    if k.size == 0:
        raise ParameterError(f"--psf file {path} holds an empty array (shape {k.shape})")
    return k


NOISE_SIGMA_MAX = 1e3
"""The largest --noise-sigma, in multiples of the layer's peak (or of white, 1, if the peak is
lower): beyond it the image is all noise, and its square overflows."""


def _check_noise_sigma(sigma: float | None, image) -> None:
    """--noise-sigma: finite, >= 0 and at most :data:`NOISE_SIGMA_MAX` x max(peak, 1)."""
    if sigma is None:
        return
    peak = max(float(np.nanmax(np.abs(image))) if np.size(image) else 0.0, 1.0)
    hi = NOISE_SIGMA_MAX * peak
    if not 0 <= sigma <= hi:  # also NaN
        raise ParameterError(
            f"--noise-sigma must be in [0, {hi:.4g}] (the layer's units: up to "
            f"{NOISE_SIGMA_MAX:g}x its peak or white, {peak:.4g}), got {sigma!r}"
        )


def _deconvolve_layer(layers: list[str], layer: str | None) -> str:
    """The layer to deblur: as asked, else ``noisy`` when the capture has one (a sensor
    capture), else ``capture``."""
    if layer is not None:
        return layer
    return "noisy" if "noisy" in layers else "capture"


def _noise(args, kw: dict, how: str | None, image, layer: str, layers, record) -> dict:
    """The noise the deconvolver is told, and where it came from; sets ``noise_sigma`` in
    ``kw`` for the methods that take one. --noise-sigma, else the noise the capture recorded
    (a sensor capture's belongs to its ``noisy`` layer; its other layers are noiseless), else
    the layer's wavelet estimate (what the deconvolver would estimate itself)."""
    from .restore.deconvolve import estimate_noise_sigma

    if "noise" in kw:  # hl/tv on the sensor's own layer: its Poisson-Gaussian model
        return {"sigma": record.known_noise_sigma, "source": how}
    if args.method not in ("wiener", "hl", "tv", "bm3d"):
        return {"sigma": None, "source": f"not used by {args.method}"}
    known = record is not None and (layer == "noisy" or "noisy" not in layers)
    if args.noise_sigma is not None:
        sigma, source = args.noise_sigma, "--noise-sigma"
    elif known and record.known_noise_sigma is not None:
        sigma, source = record.known_noise_sigma, "the capture's JSON (noise_sigma)"
    else:
        sigma = estimate_noise_sigma(np.asarray(image, float))
        source = "estimated from the layer (wavelet MAD)"
    kw["noise_sigma"] = sigma
    return {"sigma": sigma, "source": source}


def _sparse_options(args, layer: str, record) -> tuple[dict, str | None]:
    """The hl/tv keywords: --colour, and the sensor's Poisson-Gaussian noise for its own noisy
    layer (unless --noise-sigma). Returns (kwargs, noise description or None)."""
    if args.method not in ("hl", "tv"):
        if args.colour is not None:
            raise ParameterError(f"--colour needs --method hl or tv, not {args.method}")
        return {}, None
    kw = {} if args.colour is None else {"colour": args.colour}
    own = record is not None and record.sensor is not None and layer == "noisy"
    if own and args.noise_sigma is None:
        kw["noise"] = layer_noise(record)
        return kw, "the sensor's Poisson-Gaussian noise"
    return kw, None


_FILE_SUFFIXES = {".txt", ".json", ".npy", ".tif", ".tiff", ".jpg", ".jpeg", ".hdr", ".pfm"}
"""An --out with one of these is a mistyped file name, not a folder."""


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
    from .study.score import score_capture

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


def _cmd_deconvolve(args: argparse.Namespace) -> int:
    import time

    capture = Path(args.capture)
    psf_file = capture.parent / "psf_rendered.exr" if args.psf == "rendered" else Path(args.psf)
    inputs = [capture] if args.psf in ("analytic", "robust") else [capture, psf_file]
    out, single_file = _deconvolve_out(args, inputs)  # before reading: a slip costs nothing
    layers = read_exr(capture)
    layer = _deconvolve_layer(list(layers), args.layer)
    image = pick_layer(layers, layer, capture)
    _check_noise_sigma(args.noise_sigma, image)
    record = _capture_record(capture, required=args.psf in ("analytic", "robust"))
    kw, how = _sparse_options(args, layer, record)
    psf = _load_psf(args.psf, capture, record)
    noise = _noise(args, kw, how, image, layer, layers, record)
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


def _noise_words(noise: dict, model: str | None) -> str:
    """The noise for the summary line: the sensor's model, a sigma and its source, or not
    used."""
    sigma = noise["sigma"]
    if model is not None or sigma is None:
        return model or noise["source"]
    if noise["source"].startswith("estimated"):
        return f"estimated, sigma {sigma:.4g}"
    return f"sigma {sigma:.4g} ({noise['source']})"


def _psf_json(args, psf: _PSF) -> dict:
    """The PSF's entry in deconvolved.json."""
    shift = -psf.t0_offset_px if psf.origin == "t0" else 0.0
    return {
        "psf": {
            "source": args.psf,
            "file": None if psf.file is None else str(psf.file),
            "size_px": list(psf.kernel.shape[:2]),
            "origin": psf.origin,
            "result_shifted_px": shift,  # onto the pinhole image, the capture's registration
        }
    }


def _write_deconvolved_file(out: Path, est, force: bool) -> None:
    if out.suffix == ".exr":
        write_exr(out, {"deconvolved": est}, force=force)
    else:
        write_png(out, srgb8(est), force=force)


def _write_deconvolved(out: Path, est, record, info: dict, noise: dict) -> None:
    """deconvolved.exr (the layer's units), .png (exposed like capture.png) and .json."""
    from .exposure.record import layer_unit

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


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from .experiments import reproduce

    names = list(reproduce.FIGURES) if args.figure == "all" else [args.figure]
    if not 0 <= args.seed < 2**31:
        raise ParameterError(f"--seed must be an integer in [0, 2^31), got {args.seed}")
    from .study.engine import check_workers, probe_scheduler

    workers = check_workers(args.workers, len(names))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    out = writable_dir(args.out)
    for fig in reproduce.run(
        names, out, args.quick, args.force, args.seed, workers, args.scheduler
    ):
        print(f"{fig.name}: {out / fig.name}.csv .png .md ({fig.seconds:.1f} s)")
    return 0


def _sensor_model(name: str):
    from .sensor.model import SensorModel

    return SensorModel.from_preset(name)


def _cmd_render(args: argparse.Namespace) -> int:
    from .exposure.capture import CaptureSpec, check_budget, render_capture
    from .io.lock import output_lock

    target = _noise_target(args)
    spec = CaptureSpec(
        scene=args.scene,
        mode=args.mode,
        **_sensor_size(args),
        spp=64 if args.spp is None else args.spp,
        seed=args.seed,
        max_step_px=args.max_step_px,
        per_pattern=args.per_pattern,
        cover_px_per_ms=args.cover,
        preset=args.preset,
        object_depth_mm=args.depth,
        schedule=args.schedule,
        passes=args.passes,
        sampler=args.sampler,
    )
    if args.schedule is not None:  # read and check it before any rendering
        from .exposure.capture import capture_design

        capture_design(spec)
    model = _sensor_model(args.sensor) if args.sensor else None
    if args.light_level is not None and model is None:
        raise ParameterError("--light-level needs --sensor")
    if args.light_level is not None:  # refuse before rendering, not after
        check_positive("--light-level", args.light_level, "photons/px/ms")
    for flag in ("max_steps", "max_samples"):
        check_positive("--" + flag.replace("_", "-"), getattr(args, flag))
    if not args.checkpoint_every >= 0:  # 0: after every step
        raise ParameterError(f"--checkpoint-every must be >= 0 s, got {args.checkpoint_every!r}")
    check_budget(
        spec, args.max_samples, not args.no_truth, target is not None
    )  # render_capture checks again; this is before any file
    out = Path(args.out)
    if (out / "capture.exr").exists() and not args.force:
        raise ParameterError(f"--out {out} already holds a capture; pass --force to overwrite it")
    with _new_folder(out), output_lock(out):
        if args.force:
            _discard_partial(out / ".partial")
        cap = render_capture(
            spec,
            partial_dir=out / ".partial",
            progress=not args.quiet,
            save_every_s=args.checkpoint_every,
            max_steps=args.max_steps,
            max_samples=args.max_samples,
            truth=not args.no_truth,
            target=target,
            keep_partial=True,
        )
        if model is not None:
            from .sensor.apply import add_sensor_layers

            add_sensor_layers(cap, model, args.sensor, args.light_level, spec.seed)
        paths = _write_or_rescue(cap, out, args)
    m = cap.meta
    w, h = spec.image_size
    where = f"{w}x{h}" + (f" window at ({spec.crop[0]}, {spec.crop[1]})" if spec.crop else "")
    err = m["render_error"]
    print(
        f"{spec.mode} capture of {spec.scene}: {where} of a {spec.width}x{spec.height} sensor, "
        f"{m['effective_spp']} spp in {err['passes']} passes of {m['n_steps']} step(s), "
        f"{m['render_seconds']:.1f} s -> " + ", ".join(p.name for p in paths)
    )
    print(_scale_line(m["optics"], m["coded_design"]))
    print(error_line(err))
    print(
        "layers: "
        + ", ".join(["capture", *cap.extra_layers, *(["mc_sigma"] if args.mc_sigma_layer else [])])
    )
    return 0


def _discard_partial(partial: Path) -> None:
    """--force starts afresh: drop the finished steps of an earlier run (after the lock)."""
    import shutil

    if partial.exists():
        shutil.rmtree(partial)
        warnings.warn(
            f"--force: discarded the finished steps of an earlier run in {partial}; rendering "
            "afresh",
            PacamWarning,
            stacklevel=2,
        )


def _write_or_rescue(cap, out: Path, args: argparse.Namespace) -> list[Path]:
    """Write the capture; only then drop its rendered passes (``DIR/.partial``). A failed
    write (a full disk) keeps them, tries the files in a temporary folder too, and says where
    both are: the same command resumes from the passes without rendering again."""
    import shutil
    import tempfile

    from .exposure.capture import write_capture

    try:
        paths = write_capture(cap, out, force=args.force, error_layer=args.mc_sigma_layer)
    except OSError as exc:
        kept = out / ".partial"
        where = f"the rendered passes are kept in {kept}" if kept.is_dir() else "nothing was kept"
        try:
            rescue = Path(tempfile.mkdtemp(prefix="pacam-rescue-"))
            write_capture(cap, rescue, force=True, error_layer=args.mc_sigma_layer)
            where += f", and the capture was written to {rescue}"
        except OSError:
            pass
        raise OSError(
            f"writing the capture to {out} failed ({exc}); {where}: free the space and run the "
            "same command again, which resumes without rendering"
        ) from None
    shutil.rmtree(out / ".partial", ignore_errors=True)
    return paths


def _noise_target(args: argparse.Namespace):
    """The render's noise target from --noise-ratio (with --sensor) or --noise-target."""
    from .exposure.estimate import AbsoluteTarget

    given = [f for f in ("noise_ratio", "noise_target") if getattr(args, f) is not None]
    if not given:
        return None
    if len(given) == 2:
        raise ParameterError("give --noise-ratio or --noise-target, not both")
    if args.spp is not None:
        raise ParameterError(
            f"--spp and --{given[0].replace('_', '-')} both set the samples: give one "
            "(a target renders until it is met, within --max-samples)"
        )
    if args.noise_target is not None:
        return AbsoluteTarget(check_positive("--noise-target", args.noise_target))
    if args.sensor is None:
        raise ParameterError(
            "--noise-ratio needs --sensor (it scales the sensor's noise); without a sensor, "
            "give an absolute --noise-target"
        )
    from .sensor.apply import SensorTarget

    ratio = check_positive("--noise-ratio", args.noise_ratio)
    return SensorTarget(ratio, ((args.sensor, args.light_level),))


def error_line(err: dict) -> str:
    """One line: the capture's Monte Carlo sigma, against the sensor's, its time steps' error,
    and its cost."""
    ratio = err.get("ratio_to_sensor")
    vs = f" ({ratio:.2g}x the sensor's)" if ratio is not None else ""
    target = ""
    if "target_sigma" in err:
        met = "met" if err["target_met"] else "NOT met"
        target = f", target {err['target_sigma']:.3g} {met}"
    steps = (
        "time-step error 0 (stratified random times: inside the MC sigma)"
        if err["time_steps_per_pass"]
        else "no time steps (static)"
    )
    return (
        f"MC sigma {err['mc_sigma']:.3g}{vs}{target}, {steps}, {err['seconds']:.1f} s "
        f"({err['passes']} passes, {err['spp']} spp, {err['sampler']})"
    )


def _sensor_size(args: argparse.Namespace) -> dict:
    """width, height and crop: ``--crop`` alone is a window of the preset's full sensor."""
    full = preset(args.preset)
    if args.crop is None:
        return {"width": args.width or 320, "height": args.height or 240}
    width, height = args.width or full.width_px, args.height or full.height_px
    from .exposure.capture import parse_crop

    return {"width": width, "height": height, "crop": parse_crop(args.crop)}


def _scale_line(optics: dict, coded: dict) -> str:
    """The camera's px quantities at the capture's resolution (they shrink with binning)."""
    if coded.get("schedule") == "designed":  # no parabola: no a_i, no invariant range
        return (
            f"at {optics['width_px']}x{optics['height_px']} px: r = {optics['r_px']:.3g} px; "
            f"a designed schedule of {coded['n_patterns']} openings (pacam optimize)"
        )
    return (
        f"at {optics['width_px']}x{optics['height_px']} px: r = {optics['r_px']:.3g} px, "
        f"a_i = {optics['a_i_px_per_ms2']:.3g} px/ms^2; the coded design keeps |s| <= "
        f"{coded['velocity_range_px_per_ms']:.3g} px/ms invariant (r = {coded['r_px']:.3g} px)"
    )


@contextlib.contextmanager
def _new_folder(out: Path):
    """Create ``out`` (proven writable); if the command fails and leaves it empty, remove it."""
    created = not out.exists()
    writable_dir(out)
    try:
        yield out
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise


def _cmd_validate_psf(args: argparse.Namespace) -> int:
    from .experiments import validate_psf as validate
    from .study.engine import check_workers, probe_scheduler

    grid = validate.QUICK if args.quick else validate.FULL
    workers = check_workers(args.workers, len(grid.depths_mm) * len(grid.f_numbers))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    s = validate.run(
        grid, args.out, args.force, not args.quiet, workers=workers, scheduler=args.scheduler
    )
    print(
        f"validate-psf ({grid.name}): {s['points']} points in {s['seconds']:.1f} s; r within "
        f"1 %: {s['r_pass']}/{s['r_points']} (max {s['r_max_err_pct']:.3f} %); a_i within 1 %: "
        f"{s['a_i_pass']}/{s['points']} (max {s['a_i_max_err_pct']:.3f} %); L1 at the noise "
        f"floor: {s['l1_pass']}/{s['points']} (L1/floor median {s['l1_ratio_median']:.2f}); "
        f"Eq. 14 vs 16 patterns up to L1 {s['eq14_vs_discrete_max']:.3f}"
    )
    print(f"wrote {Path(args.out)}/: {', '.join(s['files'])}")
    return 0


def _cmd_validate_scene(args: argparse.Namespace) -> int:
    from .experiments import scene_report
    from .experiments import validate_scene as vs
    from .exposure.capture import parse_crop

    if args.speed is not None:
        check_positive("--speed", args.speed, "px/ms")
    check = vs.SceneCheck(
        scene=args.scene,
        mode=args.mode,
        width=args.width,
        height=args.height,
        crop=parse_crop(args.crop) if args.crop else None,
        spp=args.spp,
        seed=args.seed,
        max_step_px=args.max_step_px,
        preset=args.preset,
        cover_px_per_ms=args.cover,
        f_number=args.f_number,
        r_px=args.r_px,
        object_depth_mm=args.depth,
        speed_px_per_ms=args.speed,
        quantum_px=args.quantum,
        quick=args.quick,
    )
    s = vs.run(check, args.out, args.force, not args.quiet)
    print(f"validate-scene {args.scene}: {s['seconds']:.1f} s -> {Path(args.out)}/")
    for line in scene_report.findings(s["rows"], s["profile_width_px"]):
        print(line)
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    from .study import load_study, run_study
    from .study.engine import check_scheduler, check_workers, probe_scheduler

    check_scheduler(args.scheduler)
    spec = load_study(args.spec, quick=args.quick)  # every key checked before any work
    workers = check_workers(args.workers, len(spec.groups()))
    probe_scheduler(args.scheduler)  # before any work: Dask's own handshake has no time limit
    where = args.scheduler or (f"{workers} local workers" if workers else "serially, in-process")
    groups = len(spec.groups())
    print(f"study {spec.name}: {len(spec.points)} points in {groups} renders, {where}")
    if args.budget is not None:
        check_positive("--budget", args.budget, "h")

    def estimate(summary) -> None:
        print(
            f"study {spec.name}: the renders still to do need about "
            f"{summary.estimate_s / 3600:.2f} h (predicted from their pilot passes, kept)",
            flush=True,
        )

    try:
        s = run_study(
            spec,
            args.out,
            workers,
            args.scheduler,
            args.keep_images,
            args.force,
            not args.quiet,
            budget_hours=args.budget,
            on_estimate=estimate,
        )
    except (KeyboardInterrupt, CaptureInterrupted) as exc:  # the latter: Ctrl-C in a serial render
        _study_interrupted(Path(args.out), len(spec.points), exc)
        return 130
    print(
        f"study {s.name}: {s.ran} points run, {s.skipped} already done, {s.failed} failed, "
        f"{s.seconds:.1f} s -> {Path(args.out)}/{{{','.join(s.files)}}}"
    )
    return 1 if s.failed else 0


def _study_interrupted(out: Path, points: int, exc: BaseException) -> None:
    """Say how many points ``results.csv`` keeps, and whether the render cut short kept its
    finished steps (a serial study's capture saves them in its ``.partial``)."""
    from .study.results import RESULTS, read_csv

    try:
        saved = len(read_csv(out / RESULTS))
    except (OSError, ValueError):
        saved = 0
    why = str(exc).split(";")[0] if isinstance(exc, CaptureInterrupted) else "interrupted"
    kept = " (the render under way kept its finished steps)" if "saved in" in str(exc) else ""
    print(
        f"pacam study: {why}; {saved} of {points} points are saved in {out / RESULTS}{kept}: "
        "run the same command again to resume",
        file=sys.stderr,
    )


def _add_design_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="prototype", help="base camera (default: prototype)")
    p.add_argument("--depth", type=float, metavar="MM", help="object depth Z, mm (default 500)")
    p.add_argument("--exposure", type=float, metavar="MS", help="exposure 2T, ms (default 45)")
    p.add_argument(
        "--max-velocity",
        type=float,
        metavar="PX_PER_MS",
        help="fastest object speed to keep motion-invariant; solves for R, focus, r and a_i",
    )
    p.add_argument(
        "--f-number", type=float, metavar="N", help="fix the opening (with --max-velocity)"
    )
    p.add_argument(
        "--r-px", type=float, metavar="PX", help="fix the defocus radius (with --max-velocity)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")


def _version() -> str:
    from importlib.metadata import version

    return version("pacam_render")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pacam", description="Programmable-aperture motion-invariant camera simulator"
    )
    parser.add_argument("--version", action="version", version=f"pacam {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_design(sub)
    _add_psf(sub)
    _add_deconvolve(sub)
    _add_reproduce(sub)
    _add_render(sub)
    _add_optimize(sub)
    _add_validate_psf(sub)
    _add_validate_scene(sub)
    _add_study(sub)
    _add_demo(sub)
    return parser


def _add_design(sub) -> None:
    p = sub.add_parser("design", help="derive the camera's optics, schedule, r and a_i")
    _add_design_args(p)
    p.set_defaults(func=_cmd_design)


def _add_psf(sub) -> None:
    p = sub.add_parser("psf", help="write an analytic PSF (EXR, PNG preview, JSON)")
    p.add_argument("--preset", default="prototype")
    p.add_argument("--depth", type=float, required=True, metavar="MM", help="point depth, mm")
    p.add_argument("--velocity", type=float, required=True, metavar="PX_PER_MS")
    p.add_argument("--mode", default="coded", choices=MODES_WITH_PSF)
    p.add_argument("--size", type=int, metavar="PX", help="odd kernel side (default: fits the PSF)")
    p.add_argument("--width", type=int, metavar="W", help="sensor px (default: the preset's, 1280)")
    p.add_argument("--height", type=int, metavar="H", help="sensor px (default: 960)")
    p.add_argument("--crop", metavar="X,Y,W,H", help="the capture's window (recorded)")
    p.add_argument(
        "--like",
        metavar="CAPTURE.exr",
        help="copy a capture's sensor size and crop from its JSON, so the kernel fits it",
    )
    p.add_argument(
        "--render", action="store_true", help="also ray-trace it (ptracer): psf_rendered.exr"
    )
    p.add_argument(
        "--spp",
        type=int,
        metavar="N",
        help="with --render: samples per film pixel per pattern window (default: about 2^18 "
        "particles per window)",
    )
    p.add_argument("--seed", type=int, metavar="S", help="with --render: seed (default 0)")
    p.add_argument(
        "--max-samples",
        type=int,
        default=DEFAULT_MAX_SAMPLES,
        metavar="N",
        help=f"with --render: refuse more than N = spp x film px x windows particles (default "
        f"2^35 = {DEFAULT_MAX_SAMPLES})",
    )
    p.add_argument(
        "--film",
        default="window",
        choices=("window", "crop"),
        help="with --render: a kernel-sized film (default) or a crop of the 1280x960 film "
        "(ptracer then traces the whole film's spp x 1280 x 960 particles per window)",
    )
    p.add_argument(
        "--origin",
        choices=("t0", "pinhole"),
        help="what the centre pixel stands for: the t = 0 image (default) or the pinhole image "
        "(as 'deconvolve --psf analytic' registers captures; the default with --like). "
        "psf.json records it, and deconvolve moves a t0 kernel's result onto the pinhole image",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true", help="overwrite existing results")
    p.set_defaults(func=_cmd_psf)


def _add_deconvolve(sub) -> None:
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
        help="default hl (hyper-Laplacian prior); bm3d is optional: pip install bm3d "
        f"({BM3D_LICENCE})",
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
        "--out",
        required=True,
        metavar="DIR",
        help="folder for deconvolved.exr, .png and .json (method, PSF, noise, seconds and the "
        "score against sharp); a path ending in .exr or .png writes that one file, as before",
    )
    p.add_argument("--force", action="store_true", help="overwrite existing results")
    p.set_defaults(func=_cmd_deconvolve)


def _add_reproduce(sub) -> None:
    from .experiments.reproduce import FIGURES

    p = sub.add_parser("reproduce", help="the paper's simulation figures: CSV, PNG, Markdown")
    p.add_argument("figure", choices=[*FIGURES, "all"])
    p.add_argument("--quick", action="store_true", help="fewer images and points (< 1 min each)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    _add_engine_args(p)
    p.add_argument("--force", action="store_true", help="overwrite existing figure files")
    p.set_defaults(func=_cmd_reproduce)


def _cmd_optimize(args: argparse.Namespace) -> int:
    from .io.lock import output_lock
    from .optimize.run import run_optimize
    from .optimize.search import Problem, check_problem, reference_design

    problem = Problem(
        max_velocity_px_per_ms=args.max_velocity,
        depth_range_mm=_depth_range(args.depth_range, args.preset),
        n_patterns=args.n_patterns,
        sensor=args.sensor,
        light_level=args.light_level,
        preset=args.preset,
        f_number=args.f_number,
        r_px=args.r_px,
        free_radius=args.free_radius,
    )
    check_problem(problem)
    reference_design(problem)  # the parabola must cover the range: refused before any output
    for flag in ("starts", "iterations"):
        v = getattr(args, flag)
        if v is not None and (v < 1):
            raise ParameterError(f"--{flag} must be an integer >= 1, got {v!r}")
    if not 0 <= args.seed < 2**32:
        raise ParameterError(f"--seed must be an integer in [0, 2^32), got {args.seed!r}")
    out = prepare_out_dir(args.out, args.force)
    with _new_folder(out), output_lock(out):  # an interrupt before any file leaves no folder
        doc = run_optimize(problem, out, quick=args.quick, seed=args.seed, force=args.force,
                           starts=args.starts, iterations=args.iterations,
                           progress=not args.quiet)  # fmt: skip
    print((out / "report.md").read_text())
    gain = doc["objective_worst"] - doc["parabola_objective_worst"]
    print(f"worst-case gain over the parabola at equal light: {gain:+.2f} dB (predicted)")
    print(f"written: {out / 'schedule.json'}, report.md, 4 plots, lcos/ ({doc['n_patterns']} PNG)")
    return 0


def _depth_range(text: str | None, preset_name: str) -> tuple[float, float]:
    if text is None:
        d = preset(preset_name).object_depth_mm
        return d, d
    try:
        near, far = (float(v) for v in text.split(","))
    except ValueError:
        raise ParameterError(f"--depth-range must be NEAR,FAR in mm, got {text!r}") from None
    return near, far


def _add_optimize(sub) -> None:
    p = sub.add_parser("optimize", help="design the aperture schedule for a speed/depth range")
    p.add_argument(
        "--max-velocity",
        type=float,
        required=True,
        metavar="PX_PER_MS",
        help="cover speeds |s| <= this, px/ms of the preset's sensor",
    )
    p.add_argument("--depth-range", metavar="NEAR,FAR", help="mm (default: the preset's depth)")
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help="photons/px/ms of white through the full lens (default 300, the demo's)",
    )
    p.add_argument(
        "--sensor",
        default="grasshopper-icx285",
        help="sensor noise preset (default grasshopper-icx285; paper: sigma 0.01)",
    )
    p.add_argument("--n-patterns", type=int, default=16, metavar="N", help="default 16")
    p.add_argument(
        "--free-radius",
        action="store_true",
        help="also choose the opening's radius (light counted through the noise)",
    )
    p.add_argument("--f-number", type=float, metavar="N", help="the parabola's opening")
    p.add_argument("--r-px", type=float, metavar="PX", help="the parabola's defocus radius")
    p.add_argument("--preset", default="prototype", help="base camera (default: prototype)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="random starts (default 0)")
    p.add_argument("--starts", type=int, metavar="K", help="local searches (default 6; quick 2)")
    p.add_argument(
        "--iterations",
        type=int,
        metavar="I",
        help="L-BFGS-B iterations per start (default 100; quick 30)",
    )
    p.add_argument("--quick", action="store_true", help="a coarse grid, 2 short starts")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true", help="overwrite results in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_optimize)  # fmt: skip


def _add_render(sub) -> None:
    p = sub.add_parser("render", help="render a capture of a scene in one mode")
    p.add_argument("scene", help="train, soccer, walker, or a path to a Mitsuba .xml scene")
    p.add_argument(
        "--mode",
        default="coded",
        help=f"{', '.join(MODES)} (see pacam_render.model.modes; default coded)",
    )
    p.add_argument(
        "--width",
        type=int,
        metavar="W",
        help="sensor px (default 320, a binned sensor; with --crop, the preset's 1280)",
    )
    p.add_argument(
        "--height", type=int, metavar="H", help="sensor px (default 240; with --crop, 960)"
    )
    p.add_argument(
        "--crop",
        metavar="X,Y,W,H",
        help="render only this window of the sensor, in its px: the camera at its real scale",
    )
    p.add_argument("--preset", default="prototype", help="base camera (default: prototype)")
    p.add_argument(
        "--spp", type=int, metavar="N", help="samples per pixel, over all passes (default 64)"
    )
    p.add_argument(
        "--passes",
        type=int,
        default=2,
        metavar="P",
        help="independent passes; their spread is the Monte Carlo error (default 2)",
    )
    p.add_argument(
        "--sampler",
        default=DEFAULT_SAMPLER,
        choices=list(SAMPLERS),
        help=f"Mitsuba's sample generator (default {DEFAULT_SAMPLER}: most error per second)",
    )
    p.add_argument(
        "--noise-ratio",
        type=float,
        metavar="R",
        help="render until the Monte Carlo sigma is at most R x the sensor's noise (--sensor)",
    )
    p.add_argument(
        "--noise-target",
        type=float,
        metavar="SIGMA",
        help="render until the Monte Carlo sigma is at most SIGMA (the capture's units)",
    )
    p.add_argument(
        "--mc-sigma-layer",
        action="store_true",
        help="write the per-pixel Monte Carlo sigma as an mc_sigma layer in capture.exr",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S")
    p.add_argument(
        "--max-step-px",
        type=float,
        default=0.5,
        metavar="PX",
        help="largest image motion between time steps (default 0.5 px)",
    )
    p.add_argument("--per-pattern", action="store_true", help="also keep per-pattern images")
    p.add_argument(
        "--no-truth",
        action="store_true",
        help="leave out the ground-truth layers sharp, depth, object_id and velocity",
    )
    p.add_argument(
        "--cover",
        type=float,
        metavar="PX_PER_MS",
        help="coded/levin: solve the design so this speed (preset px) is motion-invariant",
    )
    p.add_argument(
        "--schedule",
        metavar="SCHEDULE.json",
        help="coded: show a designed schedule (pacam optimize's schedule.json)",
    )
    p.add_argument(
        "--depth",
        type=float,
        metavar="MM",
        help="the object depth the design is made for (default: the preset's, 500 mm)",
    )
    p.add_argument(
        "--sensor",
        metavar="PRESET",
        help="add raw and noisy layers: paper, grasshopper-icx285, or a .json/.toml preset file",
    )
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help="photons/px/ms of white through the full aperture (default 7000)",
    )
    _add_limit_args(p)
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true", help="overwrite an existing capture")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_render)


def _add_limit_args(p: argparse.ArgumentParser) -> None:
    """Bounds on a capture's work, and how often it saves its finished steps."""
    p.add_argument(
        "--max-steps",
        type=int,
        default=DEFAULT_MAX_STEPS,
        metavar="N",
        help=f"refuse a capture of more time steps (default {DEFAULT_MAX_STEPS})",
    )
    p.add_argument(
        "--max-samples",
        type=int,
        default=DEFAULT_MAX_SAMPLES,
        metavar="N",
        help=f"refuse more than N = spp x width x height samples (default 2^35 = "
        f"{DEFAULT_MAX_SAMPLES}, about 1.5 h on 2 cores)",
    )
    p.add_argument(
        "--checkpoint-every",
        type=float,
        default=5.0,
        metavar="S",
        help="seconds between saves of the finished steps to DIR/.partial (default 5)",
    )


def _add_validate_psf(sub) -> None:
    p = sub.add_parser(
        "validate-psf", help="rendered PSFs against Eqs. 12, 14, 18 on a grid: CSV, PNG, Markdown"
    )
    p.add_argument("--quick", action="store_true", help="small grid, modest budget (~30 s)")
    _add_engine_args(p)
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true", help="overwrite results in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_validate_psf)


def _add_validate_scene(sub) -> None:
    from .psf.scene import MODEL_MODES, QUANTUM_PX

    p = sub.add_parser(
        "validate-scene",
        help="a rendered scene against the per-surface convolution model, by region",
    )
    p.add_argument("scene", help="train, soccer, walker, or a path to a Mitsuba .xml scene")
    p.add_argument("--mode", default="coded", choices=MODEL_MODES)
    p.add_argument("--width", type=int, metavar="W", help="sensor px (default the preset's)")
    p.add_argument("--height", type=int, metavar="H", help="sensor px (default the preset's)")
    p.add_argument(
        "--crop",
        metavar="X,Y,W,H",
        help="the window (default: around the moving objects, padded by the PSF's reach)",
    )
    p.add_argument("--preset", default="prototype", help="base camera (default: prototype)")
    p.add_argument("--spp", type=int, default=64, metavar="N", help="samples per pixel (64)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seeds S and S+1 (0)")
    p.add_argument(
        "--max-step-px", type=float, default=0.5, metavar="PX", help="motion per step (0.5)"
    )
    p.add_argument("--cover", type=float, metavar="PX_PER_MS", help="solve the design for it")
    p.add_argument("--f-number", type=float, metavar="N", help="with --cover: the opening")
    p.add_argument("--r-px", type=float, metavar="PX", help="with --cover: the defocus radius")
    p.add_argument("--depth", type=float, metavar="MM", help="the design's object depth")
    p.add_argument(
        "--speed",
        type=float,
        metavar="PX_PER_MS",
        help="scale the scene's motions so its fastest object moves this fast (preset px)",
    )
    p.add_argument(
        "--quantum",
        type=float,
        default=QUANTUM_PX,
        metavar="PX",
        help=f"the model's PSF quantum (default {QUANTUM_PX} px)",
    )
    p.add_argument("--quick", action="store_true", help="a small window at 16 spp (< 1 min)")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--force", action="store_true", help="overwrite results in DIR")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_validate_scene)


def _add_study(sub) -> None:
    p = sub.add_parser(
        "study", help="a rendered sweep (capture, sensor, deconvolution, scores) on Dask"
    )
    p.add_argument("spec", metavar="SPEC", help="a study TOML file, or crossover or speed")
    p.add_argument("--out", required=True, metavar="DIR", help="results.csv, report.md, plots")
    p.add_argument("--quick", action="store_true", help="the study's small version")
    _add_engine_args(p)
    p.add_argument("--keep-images", action="store_true", help="keep each point's EXR layers")
    p.add_argument(
        "--budget",
        type=float,
        metavar="HOURS",
        help="refuse the study if its renders, predicted from pilot passes, take longer",
    )
    p.add_argument("--force", action="store_true", help="start afresh over other results")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_study)


def _add_engine_args(p: argparse.ArgumentParser) -> None:
    """Where the command's independent tasks run (:mod:`pacam_render.study.engine`)."""
    p.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="worker processes of a local Dask cluster (default: one per core, at most one per "
        "task; 0: serially, in this process)",
    )
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on an existing Dask cluster (tcp://host:8786)"
    )


def _add_demo(sub) -> None:
    from .experiments.demo import DEMO_SPP

    p = sub.add_parser("demo", help="the main job on built-in defaults")
    p.add_argument("--out", default="demo_out", metavar="DIR", help="default demo_out/")
    p.add_argument(
        "--width",
        type=int,
        help="render the whole frame of a binned sensor this wide instead of a window of the "
        "full 1280x960 one (the default: the camera at its real pixel scale)",
    )
    p.add_argument("--height", type=int, help="with --width: the binned sensor's height")
    p.add_argument("--spp", type=int, default=DEMO_SPP, help=f"default {DEMO_SPP}")
    p.add_argument("--force", action="store_true", help="overwrite a previous demo in DIR")
    p.set_defaults(func=_cmd_demo)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    name = f"pacam {args.command}"
    with warnings.catch_warnings(), _terminate_as_interrupt():
        warnings.showwarning = _note_printer(name)
        try:
            _check_common(args)
            return args.func(args)
        except ParameterError as exc:  # a file's keys stay keys; a parameter becomes its flag
            words = str(exc) if isinstance(exc, FileKeyError) else _user_words(str(exc))
            print(f"{name}: error: {words}", file=sys.stderr)
            return 2
        except CaptureInterrupted as exc:
            print(f"{name}: {exc}", file=sys.stderr)
            return 130
        except KeyboardInterrupt:
            print(f"{name}: interrupted", file=sys.stderr)
            return 130
        except BrokenPipeError:  # e.g. `pacam design | head`: the reader left, nothing is wrong
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's final flush is quiet
            return 0
        except OSError as exc:  # a disk full, a file gone: one line, not a traceback
            print(f"{name}: error: {exc}", file=sys.stderr)
            return 1


def _check_common(args: argparse.Namespace) -> None:
    """Flags that several commands share, refused before any work: a size of 0 px would
    quietly become the default (``args.width or ...``), an empty --out the current folder."""
    for flag in ("width", "height"):
        value = getattr(args, flag, None)
        if value is not None and value < 1:
            raise ParameterError(f"--{flag} must be a positive number of px, got {value}")
    out = getattr(args, "out", None)
    if out is not None and not str(out).strip():
        raise ParameterError(f"--out must name a folder or file, got {out!r}")


_FLAGS = {
    "max_step_px": "--max-step-px",
    "max_steps": "--max-steps",
    "max_samples": "--max-samples",
    "noise_ratio": "--noise-ratio",
    "budget_hours": "--budget",
    "workers": "--workers",
    "noise_target": "--noise-target",
    "cover_px_per_ms": "--cover",
    "max_velocity_px_per_ms": "--max-velocity",
    "object_depth_mm": "--depth",
    "exposure_ms": "--exposure",
    "f_number": "--f-number",
    "r_px": "--r-px",
    "light_level": "--light-level",
    "noise_sigma": "--noise-sigma",
    "quantum_px": "--quantum",
}
"""Python parameter names in library messages, and the flags a CLI user typed instead."""
_FLAG_RE = re.compile(r"(?<![\w-])(" + "|".join(_FLAGS) + r")(?![\w-])(?! \(--)")


def _user_words(message: str) -> str:
    """A library message in the CLI's words: parameter names become their flags."""
    return _FLAG_RE.sub(lambda m: _FLAGS[m.group(1)], message)


def _note_printer(name: str):
    """``warnings.showwarning`` that prints a :class:`PacamWarning` as one ``note:`` line."""
    default = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PacamWarning):
            print(f"{name}: note: {_user_words(str(message))}", file=sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    return show


@contextlib.contextmanager
def _terminate_as_interrupt():
    """SIGTERM is handled as Ctrl-C (KeyboardInterrupt), so both save and exit alike."""

    def handler(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


if __name__ == "__main__":
    sys.exit(main())
