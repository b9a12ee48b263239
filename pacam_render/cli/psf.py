"""``pacam psf``: an analytic PSF (EXR, PNG preview, JSON), optionally ray-traced too."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from ..capture.files import read_record
from ..capture.kernels import capture_diffraction
from ..errors import ParameterError, check_finite, check_positive
from ..exposure.camera import binned_pitch_mm, capture_design, full_design
from ..exposure.spec import CaptureSpec, check_crop, parse_crop
from ..io.exr import write_exr
from ..io.outputs import prepare_out_dir, write_json
from ..io.preview import write_psf_preview
from ..limits import DEFAULT_MAX_SAMPLES, PacamWarning
from ..model.camera import CameraDesign, preset
from ..model.design_file import resolve_design
from ..model.modes import MODES_WITH_PSF, capture_camera
from ..psf.analytic import MAX_LOST_FRACTION, PSFTruncationWarning, design_psf, least_lost_fraction
from ..psf.diffraction import DECONVOLUTION_MAX_LOST
from ..psf.exact_defocus import ray_kernel
from ..psf.origin import origin_record
from ..psf_render.render import check_request, render_psf
from ..render.backend import select_variant
from ..render.variant import grey_request
from ..restore.metrics import rel_l1
from .common import (
    add_design_flags,
    add_force,
    add_grey,
    add_out,
    add_quiet,
    design_spec_fields,
)

PSF_FILES = ("psf_analytic.exr", "psf_analytic.png", "psf_rendered.exr", "psf_rendered.png",
             "psf.json")  # fmt: skip
"""What ``pacam psf`` writes into ``--out``."""


def add(sub) -> None:
    p = sub.add_parser("psf", help="write an analytic PSF (EXR, PNG preview, JSON)")
    add_design_flags(p)
    p.add_argument(
        "--depth",
        type=float,
        metavar="MM",
        help="point depth, mm (default: the depth the design is made for; with --like, the "
        "capture's)",
    )
    p.add_argument("--velocity", type=float, required=True, metavar="PX_PER_MS")
    p.add_argument(
        "--mode",
        choices=MODES_WITH_PSF,
        help="default coded; with --like, the capture's mode",
    )
    p.add_argument("--size", type=int, metavar="PX", help="odd kernel side (default: fits the PSF)")
    p.add_argument("--width", type=int, metavar="W", help="sensor px (default: the preset's, 1280)")
    p.add_argument("--height", type=int, metavar="H", help="sensor px (default: 960)")
    p.add_argument("--crop", metavar="X,Y,W,H", help="the capture's window (recorded)")
    p.add_argument(
        "--like",
        metavar="CAPTURE.exr",
        help="the capture's camera, whole (design, schedule and bitmaps, sensor size, mode "
        "and crop) from its JSON, so the kernel is the one that blurred it",
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
    p.add_argument(
        "--diffraction",
        choices=("on", "off"),
        help="convolve the kernel with the opening's Fraunhofer diffraction (green, 549 nm; "
        "550 for --grey); default off, and with --like the capture's own setting",
    )
    add_grey(p, "render (with --render; the analytic PSF is one channel either way)")
    add_quiet(p)
    add_out(p)
    add_force(p, "overwrite existing results")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    args.grey = grey_request(args.grey)  # refused with an RGB PACAM_VARIANT, before any work
    if args.origin is None:  # a kernel made for a capture is centred as deconvolve centres it
        args.origin = "pinhole" if args.like is not None else "t0"
    if args.depth is not None:
        check_positive("--depth", args.depth, "mm")
    check_finite("--velocity", args.velocity)
    cam, crop, args.mode = _psf_geometry(args)
    if args.depth is not None:
        cam = cam.with_(object_depth_mm=args.depth)
    args.depth = cam.object_depth_mm
    if args.size is not None:
        _odd_size(args.size)
    seed = 0 if args.seed is None else args.seed
    if args.render:  # check everything before computing or writing anything
        check_request(cam, args.spp, seed, args.film)
        check_positive("--max-samples", args.max_samples)
    elif args.spp is not None or args.seed is not None:
        raise ParameterError("--spp and --seed need --render")
    diffraction = _diffraction(args, cam)
    out = prepare_out_dir(args.out, args.force, PSF_FILES)  # a capture's folder is fine
    k = geometric = _checked_psf(cam, args)
    if diffraction is not None:
        k = _diffracted(cam, args, k, diffraction)
    r = _rendered_psf(cam, geometric, seed, args, diffraction) if args.render else None
    # nothing is written before the render ends: an interrupt leaves no half set of files
    write_exr(out / "psf_analytic.exr", {"psf": k}, force=args.force)
    what = f"{args.mode}, s = {args.velocity:g} px/ms"
    write_psf_preview(out / "psf_analytic.png", k, f"analytic PSF, {what}", force=args.force)
    meta = {
        **cam.summary(),
        "mode": args.mode,
        "camera": cam.inputs(),  # whole: deconvolve compares it with the capture's
        "velocity_px_per_ms": args.velocity,
        "size_px": list(k.shape),
        "diffraction": diffraction,
        **({"crop": crop} if crop else {}),
        **origin_record(cam, args.mode, args.origin),
        "psf_origin": "centre pixel = where the point images at mid-exposure (t = 0)"
        if args.origin == "t0"
        else "centre pixel = where a pinhole at the lens centre images the point at t = 0",
    }
    written = "psf_analytic.exr, psf_analytic.png"
    if r is not None:
        write_exr(out / "psf_rendered.exr", {"psf": r.kernel}, force=args.force)
        title = f"rendered PSF, {what}"
        write_psf_preview(out / "psf_rendered.png", r.kernel, title, force=args.force)
        l1 = rel_l1(r.kernel, r.model)  # the model as rendered: with the rays' diffraction
        meta["rendered"] = {**r.to_json(), "l1_vs_analytic": l1}
        meta["rendered"]["variant"] = _variant()
        written += ", psf_rendered.exr, psf_rendered.png"
        versus = "the analytic PSF" + (
            " with the rays' diffraction (the channels' luminance)" if diffraction else ""
        )
        print(
            f"rendered in {r.seconds:.1f} s ({r.particles} particles, spp {r.spp}, seed "
            f"{r.seed}): L1 to {versus} {l1:.4f}, fitted a_i "
            f"{r.fitted_a_i:.5g} px/ms^2 (Eq. 18: {r.model_a_i:.5g})"
        )
    if r is None:  # a rendered kernel of an earlier run is not this record's: --force took it
        for name in ("psf_rendered.exr", "psf_rendered.png"):
            (out / name).unlink(missing_ok=True)
    write_json(out / "psf.json", meta, force=args.force)
    print(f"wrote {out}/: {written}, psf.json ({k.shape[0]}x{k.shape[1]} px)")
    return 0


def _diffracted(cam: CameraDesign, args: argparse.Namespace, k, diffraction: dict):
    """The analytic kernel ``k`` with ``diffraction`` as the rays draw it, the pixel's box
    counted once (:func:`~pacam_render.psf.exact_defocus.ray_kernel`)."""

    wl, pitch = diffraction["wavelength_nm"], diffraction["pixel_pitch_mm"]

    def build(c, f, fine):
        return design_psf(c, args.mode, args.velocity * f, fine, origin=args.origin)

    return ray_kernel(build, cam, args.mode, args.velocity, args.origin, wl, k.shape, pitch,
                      DECONVOLUTION_MAX_LOST, diffraction["psf"])  # fmt: skip


def _diffraction(args: argparse.Namespace, cam: CameraDesign) -> dict | None:
    """The diffraction the kernel gets: --diffraction, or with --like the capture's
    (:func:`~pacam_render.capture.kernels.capture_diffraction`, at the capture's pixels);
    None for none."""

    own = capture_diffraction(read_record(Path(args.like))) if args.like is not None else None
    if args.diffraction == "off" or (args.diffraction is None and own is None):
        return None
    if own is not None:
        return own

    full = resolve_design(args.design) if args.design else preset(args.preset)
    return {  # a binned sensor's pixels are larger than the preset's
        "wavelength_nm": 550.0 if args.grey else 549.0,
        "pixel_pitch_mm": binned_pitch_mm(full, cam.width_px),
        "psf": "exact",  # as a capture's disc rays draw it (psf.exact_defocus.ray_kernel)
    }


def _rendered_psf(cam: CameraDesign, k: np.ndarray, seed: int, args, diffraction=None):
    """The ray-traced kernel of the geometric kernel ``k``'s camera, with the opening's
    diffraction in the rays when ``diffraction`` (its model then too); refused beyond
    --max-samples before any rendering."""

    if args.grey:  # before the renderer activates a (colour) variant of its own
        select_variant(mono=True)
    return render_psf(
        cam, args.mode, args.velocity, size=k.shape, spp=args.spp, seed=seed, film=args.film,
        origin=args.origin, model=k, max_samples=args.max_samples, progress=not args.quiet,
        diffraction=diffraction is not None,
        pixel_pitch_mm=None if diffraction is None else diffraction["pixel_pitch_mm"],
    )  # fmt: skip


def _psf_geometry(args: argparse.Namespace) -> tuple[CameraDesign, dict | None, str]:
    """The camera, the crop to record and the mode: a capture's own (``--like``), or the
    design (``--design``/``--preset``, ``--cover``, ``--schedule``) at ``--width``/``--height``.
    A kernel's px quantities (r, a_i) follow the sensor's size; a crop does not change the
    kernel, only where it applies."""
    if args.like is not None:
        return _like_geometry(args)

    fields = design_spec_fields(args)
    full = full_design(CaptureSpec(**fields))
    width = args.width or full.width_px
    height = args.height or full.height_px
    cam = capture_design(CaptureSpec(**fields, width=width, height=height))
    mode = args.mode or "coded"
    if args.crop is None:
        return cam, None, mode
    x, y, w, h = check_crop(parse_crop(args.crop), width, height)
    crop = {"x": x, "y": y, "width": w, "height": h}
    return cam, {**crop, "sensor_width_px": width, "sensor_height_px": height}, mode


def _like_geometry(args: argparse.Namespace) -> tuple[CameraDesign, dict | None, str]:
    """A capture's camera, exactly as recorded: its mode's camera, or, for another
    ``--mode``, that mode's camera of the capture's coded design."""
    own = ("width", "height", "crop", "design", "cover", "f_number", "r_px", "schedule")
    given = [f for f in own if getattr(args, f)] + (
        ["preset"] if args.preset != "prototype" else []
    )
    if given:
        flags = ", ".join("--" + f for f in given)
        raise ParameterError(
            f"--like copies the capture's camera, size and crop: leave out {flags}"
        )
    capture = Path(args.like)
    record = read_record(capture)
    if record is None:
        raise ParameterError(f"--like needs the capture's {capture.with_suffix('.json')}")
    mode = args.mode or record.mode
    if mode not in MODES_WITH_PSF:
        raise ParameterError(
            f"--like {capture} is a {record.mode} capture, which has no PSF; give --mode, one of "
            f"{', '.join(MODES_WITH_PSF)}"
        )
    if mode == record.mode:
        return CameraDesign.from_inputs(record.camera), record.crop, mode

    design = CameraDesign.from_inputs(record.design_inputs())
    return capture_camera(design, mode), record.crop, mode


def _checked_psf(cam: CameraDesign, args: argparse.Namespace) -> np.ndarray:
    """The analytic kernel, refused if more than MAX_LOST_FRACTION of it falls outside."""

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


def _variant() -> str:
    """The Mitsuba variant that rendered (recorded in psf.json)."""
    import mitsuba as mi

    return str(mi.variant())
