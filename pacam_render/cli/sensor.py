"""``pacam sensor``: the image sensor on a capture already rendered, written as a new capture
folder (what ``pacam render --sensor`` writes, without rendering again)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import ParameterError
from ..io.lock import output_lock
from ..sensor.model import SensorModel
from ..sensor.on_capture import sensor_on_capture
from ..sensor.radiometry import DEFAULT_LIGHT_LEVEL, check_light_level
from .common import add_force, add_out, new_folder
from .render_parts.capture_out import write_or_rescue


def add(sub) -> None:
    p = sub.add_parser(
        "sensor", help="pass a rendered capture through the image sensor (raw and noisy layers)"
    )
    p.add_argument("capture", metavar="CAPTURE.exr", help="a capture.exr (or its folder)")
    p.add_argument(
        "--sensor",
        required=True,
        metavar="PRESET",
        help="paper, grasshopper-icx285, grasshopper-icx285-mono (for a grey capture: a Bayer "
        "preset is refused there), or a .json/.toml preset file; an earlier sensor's raw and "
        "noisy layers are replaced (the sensor sees the noise-free capture layer)",
    )
    p.add_argument(
        "--light-level",
        type=float,
        metavar="L",
        help=f"photons/px/ms of white through the full aperture, > 0 (default "
        f"{DEFAULT_LIGHT_LEVEL:g})",
    )
    p.add_argument(
        "--seed",
        type=int,
        metavar="S",
        help="the noise's seed (default: the capture's own, which gives what render --sensor "
        "gives)",
    )
    add_out(p, help="a new capture folder: capture.exr, capture.json, capture.png")
    add_force(p, "overwrite a capture in DIR")
    p.add_argument("--quiet", action="store_true", help="print only the summary line and notes")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    src = Path(args.capture)
    exr = src / "capture.exr" if src.is_dir() else src
    if not exr.is_file():
        raise ParameterError(f"no capture at {exr} (CAPTURE.exr)")
    try:
        SensorModel.from_preset(args.sensor)  # refused before reading the capture
    except ParameterError as exc:
        raise ParameterError(f"--sensor: {exc}") from None
    if args.light_level is not None:
        check_light_level(args.light_level, "--light-level")
    if args.seed is not None and not 0 <= args.seed < 2**32:
        raise ParameterError(f"--seed must be an integer in [0, 2^32), got {args.seed}")
    out = Path(args.out)
    if out.resolve() == exr.parent.resolve():
        raise ParameterError(f"--out {out} holds the input capture; give another folder")
    if (out / "capture.exr").exists() and not args.force:
        raise ParameterError(f"--out {out} already holds a capture; pass --force to overwrite it")
    cap = sensor_on_capture(exr, args.sensor, args.light_level, args.seed)
    with new_folder(out), output_lock(out):
        paths = write_or_rescue(cap, out, args.force, cap.mc_sigma is not None)
    print(_summary(cap, exr, paths))  # as render --quiet does, the summary always
    if not args.quiet:
        print("layers: " + ", ".join(["capture", *cap.extra_layers]))
    return 0


def _summary(cap, exr: Path, paths) -> str:
    """One line: the sensor, its light level, the noise sigma and the saturated fraction."""
    s, rec = cap.record.sensor, cap.record
    level = s.light_level_photons_per_px_per_ms
    at = "" if level is None else f" at {level:g} photons/px/ms"
    sat = "" if s.saturated_fraction is None else f", saturated {s.saturated_fraction:.2%}"
    sigma = "" if rec.noise_sigma is None else f": noise sigma {rec.noise_sigma:.4g}"
    return f"{s.preset}{at} on {exr}{sigma}{sat} -> " + ", ".join(str(p) for p in paths)
