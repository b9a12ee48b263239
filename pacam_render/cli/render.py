"""``pacam render``: a capture of a scene in one mode, optionally through the image sensor."""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from ..errors import ParameterError, check_positive
from ..exposure.direct import check_budget, render_capture
from ..exposure.estimate import AbsoluteTarget
from ..exposure.plan import grey_for_sensor, plan_capture
from ..exposure.spec import CaptureSpec, parse_crop
from ..exposure.truth import TRUTH_LAYERS
from ..io.lock import output_lock
from ..lightfield import Store, synthesize
from ..lightfield.synthesis import store_noise_note
from ..limits import PacamWarning, note
from ..model.camera import preset
from ..model.design_file import resolve_design
from ..model.modes import MODES
from ..render.samplers import DEFAULT_SAMPLER, SAMPLERS
from ..render.variant import grey_request
from ..sensor.apply import SensorTarget, add_sensor_layers, check_grey_sensor
from ..sensor.model import SensorModel
from ..sensor.radiometry import DEFAULT_LIGHT_LEVEL, check_light_level
from .common import (
    add_design_flags,
    add_force,
    add_grey,
    add_limit_args,
    add_out,
    add_quiet,
    add_seed_and_steps,
    design_spec_fields,
    new_folder,
)
from .render_parts.capture_out import error_line, optics_lines, scale_line, write_or_rescue
from .render_parts.optics_flags import add_optics


def add(sub) -> None:
    p = sub.add_parser("render", help="render a capture of a scene in one mode")
    p.add_argument(
        "scene",
        help="train, soccer, walker, family:NAME:SEED (e.g. family:occluders:12; see pacam "
        "scene generate), or a path to a Mitsuba .xml scene",
    )
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
    add_design_flags(p)
    _add_sampling(p)
    p.add_argument("--per-pattern", action="store_true", help="also keep per-pattern images")
    p.add_argument(
        "--no-truth",
        action="store_true",
        help="leave out the ground-truth layers sharp, depth, object_id and velocity",
    )
    p.add_argument(
        "--depth",
        type=float,
        metavar="MM",
        help="the object depth the design is made for (default: the design's, 500 mm for the "
        "prototype)",
    )
    _add_sensor(p)
    add_optics(p)
    p.add_argument(
        "--from",
        dest="from_store",
        metavar="STORE",
        help="synthesise the capture from a light-field store (pacam lightfield) instead of "
        "rendering it: any design of the store's scene and window, in seconds; the store sets "
        "the size, window, samples and seed",
    )
    add_grey(p)
    add_limit_args(p)
    add_out(p)
    add_force(p, "overwrite an existing capture")
    add_quiet(p)
    p.set_defaults(func=run)


def _add_sampling(p: argparse.ArgumentParser) -> None:
    """How many samples, drawn how, and to what Monte Carlo error."""
    p.add_argument(
        "--spp", type=int, metavar="N", help="samples per pixel, over all passes (default 64)"
    )
    p.add_argument(
        "--passes",
        type=int,
        metavar="P",
        help="independent passes; their spread is the Monte Carlo error (default 2; a noise "
        "target plans its own)",
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
    add_seed_and_steps(p)


def _add_sensor(p: argparse.ArgumentParser) -> None:
    """The image sensor's layers and their light level."""
    p.add_argument(
        "--sensor",
        metavar="PRESET",
        help="add raw and noisy layers: paper, grasshopper-icx285, grasshopper-icx285-mono (for "
        "--grey), or a .json/.toml preset file",
    )
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help=f"photons/px/ms of white through the full aperture (default {DEFAULT_LIGHT_LEVEL:g})",
    )


def run(args: argparse.Namespace) -> int:

    if args.from_store is not None:
        return _run_from_store(args)
    target = noise_target_from_flags(args)
    plan = _plan(args, target)
    spec = plan.spec
    model = _checked_sensor(args, spec)
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
    with new_folder(out), output_lock(out):
        if args.force:
            _discard_partial(out / ".partial")
        cap = render_capture(
            plan,
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
            add_sensor_layers(cap, model, args.sensor, args.light_level, spec.seed)
        paths = write_or_rescue(cap, out, args.force, args.mc_sigma_layer)
    _print_summary(cap, spec, paths, args.mc_sigma_layer)
    return 0


FROM_STORE_REFUSED = ("spp", "passes", "noise_ratio", "noise_target", "per_pattern")
"""Flags a synthesised capture cannot take: the store fixed its samples."""


def _run_from_store(args: argparse.Namespace) -> int:
    """``--from STORE``: the capture synthesised from a light-field store
    (:func:`~pacam_render.lightfield.synthesis.synthesize`), written as a render's."""

    for name in FROM_STORE_REFUSED:
        if getattr(args, name) not in (None, False):
            flag = "--" + name.replace("_", "-")
            raise ParameterError(f"{flag}: a capture from --from takes the store's samples")
    store = Store.open(args.from_store)
    s = store.manifest.capture
    if args.scene != s["scene"]:  # before the scene is read: its digest would say less
        raise ParameterError(
            f"the store at {args.from_store} is of scene {s['scene']!r}, not {args.scene!r}: a "
            f"store serves captures of its own scene only; synthesise from it with: pacam "
            f"render {s['scene']} --from {args.from_store} ..., or render a store of "
            f"{args.scene!r} with pacam lightfield {args.scene}"
        )
    args.width, args.height = args.width or s["width"], args.height or s["height"]
    args.grey = args.grey or bool(s["grey"])  # a grey store's captures are grey: its channels
    if args.crop is None and s["crop"]:
        args.crop = ",".join(str(v) for v in s["crop"])
    plan = _plan(args, None)  # resolved once: synthesize takes the plan
    spec = plan.spec
    model = _checked_sensor(args, spec)
    out = Path(args.out)
    if (out / "capture.exr").exists() and not args.force:
        raise ParameterError(f"--out {out} already holds a capture; pass --force to overwrite it")
    with new_folder(out), output_lock(out):
        cap = synthesize(store, plan, progress=not args.quiet)
        if args.no_truth:
            cap.extra_layers = {k: v for k, v in cap.extra_layers.items() if k not in TRUTH_LAYERS}
        if model is not None:
            add_sensor_layers(cap, model, args.sensor, args.light_level, spec.seed)
        paths = write_or_rescue(cap, out, args.force, args.mc_sigma_layer)
    _print_summary(cap, spec, paths, args.mc_sigma_layer)
    print(f"from the light-field store {args.from_store} (digest {store.digest})")
    noisy = store_noise_note(cap, spp_name="pacam lightfield --spp")
    if noisy:
        note(noisy)
    return 0


def _plan(args: argparse.Namespace, target):
    """The capture the flags ask for, resolved once (:func:`~..exposure.plan.plan_capture`):
    its design (a design file, a schedule) is read and checked here, before any rendering, and
    names the sensor when --sensor does not."""

    spec = CaptureSpec(
        scene=args.scene,
        mode=args.mode,
        **_sensor_size(args),
        spp=64 if args.spp is None else args.spp,
        seed=args.seed,
        max_step_px=args.max_step_px,
        per_pattern=args.per_pattern,
        **design_spec_fields(args),
        object_depth_mm=args.depth,
        passes=_passes(args, target),
        sampler=args.sampler,
        grey=grey_request(args.grey),  # refused with an RGB PACAM_VARIANT, before any work
        relative_illumination=args.relative_illumination,
        diffraction=args.diffraction,
        lcos_contrast=args.lcos_contrast,
        lcos_fill_factor=args.lcos_fill_factor,
        lcos_switching_ms=args.lcos_switching,
    )
    if args.sensor is not None:  # a monochrome --sensor renders one channel, as --grey
        spec = grey_for_sensor(spec, args.sensor, "--sensor")
    plan = plan_capture(spec)
    if args.sensor is None and plan.design.sensor_preset is not None:  # the design names it
        args.sensor = plan.design.sensor_preset
    return plan


def _checked_sensor(args: argparse.Namespace, spec):
    """The sensor model of --sensor (None without one), with --light-level checked and a
    Bayer sensor on a grey capture refused, before rendering."""
    model = _sensor_model(args.sensor) if args.sensor else None
    if model is not None:
        check_grey_sensor(spec.grey, model, args.sensor)
    if args.light_level is not None and model is None:
        raise ParameterError("--light-level needs --sensor")
    if args.light_level is not None:
        check_light_level(args.light_level, "--light-level")
    return model


def _print_summary(cap, spec, paths, mc_sigma_layer: bool) -> None:
    """What was rendered, where, at what scale and error, and which layers."""
    m = cap.meta
    w, h = spec.image_size
    where = f"{w}x{h}" + (f" window at ({spec.crop[0]}, {spec.crop[1]})" if spec.crop else "")
    err = m["render_error"]
    print(
        f"{spec.mode} capture of {spec.scene}: {where} of a {spec.width}x{spec.height} sensor, "
        f"{m['effective_spp']} spp in {err['passes']} passes of {m['n_steps']} step(s), "
        f"{m['render_seconds']:.1f} s -> " + ", ".join(p.name for p in paths)
    )
    print(scale_line(m["optics"], m["coded_design"]))
    print(error_line(err))
    ri = m.get("relative_illumination")
    if ri:
        print(
            f"relative illumination {ri['setting']}: {ri['min']:.3f}-{ri['max']:.3f} of the "
            "axis over the window (layer relative_illumination; deconvolve flat-fields with it)"
        )
    for line in optics_lines(m.get("optics_error")):
        print(line)
    extra = ["mc_sigma"] if mc_sigma_layer else []
    print("layers: " + ", ".join(["capture", *cap.extra_layers, *extra]))


def _passes(args: argparse.Namespace, target) -> int:
    """--passes, default 2; with a noise target, which plans two pilots and its own passes,
    a given --passes does nothing, and a note says so."""
    if args.passes is not None and target is not None:
        warnings.warn(
            f"--passes {args.passes} has no effect with a noise target: two pilot passes "
            "measure the error and the target plans the rest",
            PacamWarning,
            stacklevel=2,
        )
    return 2 if args.passes is None else args.passes


def _sensor_model(name: str):

    return SensorModel.from_preset(name)


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


def noise_target_from_flags(args: argparse.Namespace):
    """The render's noise target from --noise-ratio (with --sensor) or --noise-target."""

    given = [f for f in ("noise_ratio", "noise_target") if getattr(args, f) is not None]
    if not given:
        return None
    if len(given) == 2:
        raise ParameterError("give --noise-ratio or --noise-target, not both")
    if args.spp is not None:
        # pacam lightfield has no --max-samples: its target plans the store's spp from a pilot
        how = "within --max-samples" if hasattr(args, "max_samples") else "planned from a pilot"
        raise ParameterError(
            f"--spp and --{given[0].replace('_', '-')} both set the samples: give one "
            f"(a target renders until it is met, {how})"
        )
    if args.noise_target is not None:
        return AbsoluteTarget(check_positive("--noise-target", args.noise_target))
    if args.sensor is None:
        raise ParameterError(
            "--noise-ratio needs --sensor (it scales the sensor's noise); without a sensor, "
            "give an absolute --noise-target"
        )

    ratio = check_positive("--noise-ratio", args.noise_ratio)
    return SensorTarget(ratio, ((args.sensor, args.light_level),))


def _sensor_size(args: argparse.Namespace) -> dict:
    """width, height and crop: ``--crop`` alone is a window of the preset's full sensor."""
    if args.design is not None:
        full = resolve_design(args.design)
    else:
        full = preset(args.preset)
    if args.crop is None:
        return {"width": args.width or 320, "height": args.height or 240}
    width, height = args.width or full.width_px, args.height or full.height_px

    return {"width": width, "height": height, "crop": parse_crop(args.crop)}
