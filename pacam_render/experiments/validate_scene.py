"""``pacam validate-scene``: a whole rendered scene against the convolution model (issue 15).

The capture is rendered twice (seeds S and S + 1), each with its ground truth: the sharp
t = 0 image, depth, object ids and velocity, over a window padded by the PSFs' reach so that
the model sees what blurs into the capture's window. The model
(:func:`~pacam_render.psf.scene.convolution_model`) blurs each surface of the sharp image with
the discrete-schedule PSF of its own depth and velocity.

The error is scored in units of the Monte Carlo noise, from the two seeds' difference, in each
region (:mod:`.scene_regions`) and against the distance to a moving edge
(:mod:`.scene_error`, whose docstring gives the noise floor).

The optics are a camera's, as ``pacam render``'s (``relative_illumination`` and
``diffraction``, default :data:`~pacam_render.exposure.spec.CAMERA_OPTICS`), and the
comparison is like with like: a capture with a relative illumination is flat-fielded by its map
(the model is radiance), and when the capture includes its openings' diffraction the model is
convolved with the same Fraunhofer kernels
(:func:`~pacam_render.exposure.optics.diffraction.diffract_model`).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..capture.kernels import capture_diffraction
from ..errors import ParameterError, check_range
from ..exposure.camera import capture_design, full_design, mode_camera
from ..exposure.direct import check_budget, render_capture
from ..exposure.optics.diffraction import check_diffraction, diffract_model
from ..exposure.plan import plan_capture
from ..exposure.render_time import overall_bar
from ..exposure.spec import CAMERA_OPTICS, CaptureSpec
from ..io.outputs import prepare_out_dir
from ..model.camera import CameraDesign
from ..model.illumination import flat_field, parse_relative_illumination
from ..psf.scene import MODEL_MODES, QUANTUM_PX, beta_px_per_mm, convolution_model, window_reach_px
from ..restore.flat_field import RI_LAYER
from ..scenes import load_scene
from ..scenes.edit import scene_speed_px_per_ms, shape_speed_px_per_ms, with_speed
from ..scenes.motion import _bbox_corners, project_px
from . import scene_report
from .scene_error import edge_profile, profile_width, region_rows
from .scene_regions import moving_edge_distance, region_map

QUICK_WINDOW_PX = (160, 128)
"""The ``--quick`` window (w, h), px, centred on the fastest object's leading edge."""
QUICK_SPP = 16
MIN_WINDOW_SIDE_PX = 32
"""The smallest --crop side, px: regions away from the moving edges need room."""
QUANTUM_RANGE_PX = (0.05, 4.0)
"""The model's cell quantum, px: finer only multiplies the cells (a PSF convolution each: 1e-9
ran for minutes) below the pixel-integrated kernel's resolution; coarser is no model."""
MAX_WINDOW_PX = 1280 * 720
"""The most pixels a default window (around the moving objects) may have."""
QUANTA_PX = (1.0, 0.5, 0.25, 0.125)
"""Cell quanta of the error-against-time table (the model's discretisation)."""
MODELS = ("composite", "layered")
SEEDS = 2


@dataclass(frozen=True)
class SceneCheck:
    """What to validate: a scene, its capture (as ``pacam render``) and the model's quantum."""

    scene: str = "train"
    mode: str = "coded"
    width: int | None = None
    height: int | None = None
    crop: tuple[int, int, int, int] | None = None
    spp: int = 64
    seed: int = 0
    max_step_px: float = 0.5
    preset: str = "prototype"
    cover_px_per_ms: float | None = None
    f_number: float | None = None
    r_px: float | None = None
    object_depth_mm: float | None = None
    speed_px_per_ms: float | None = None
    quantum_px: float = QUANTUM_PX
    quick: bool = False
    design: str | None = None
    """A camera design file (or capture/PSF JSON) instead of ``preset``."""
    relative_illumination: str = CAMERA_OPTICS["relative_illumination"]
    """As ``pacam render``'s: the capture is flat-fielded before it is compared."""
    diffraction: str = CAMERA_OPTICS["diffraction"]
    """As ``pacam render``'s: where the capture includes it, so does the model."""

    def __post_init__(self) -> None:
        parse_relative_illumination(self.relative_illumination)
        check_diffraction(self.diffraction)
        if self.mode not in MODEL_MODES:
            raise ParameterError(f"mode must be one of {', '.join(MODEL_MODES)}, got {self.mode!r}")
        check_range("quantum_px", self.quantum_px, *QUANTUM_RANGE_PX, "px")
        if self.crop is not None and min(self.crop[2:]) < MIN_WINDOW_SIDE_PX:
            raise ParameterError(
                f"`crop` window must be at least {MIN_WINDOW_SIDE_PX}x{MIN_WINDOW_SIDE_PX} px "
                f"for validate-scene (regions away from the moving edges need room), got "
                f"{self.crop[2]}x{self.crop[3]}"
            )


@dataclass
class Plan:
    """The capture spec, the padded truth spec, and where the capture sits inside the truth."""

    spec: object
    truth_spec: object
    desc: object
    offset: tuple[int, int]
    margin_px: int
    speed_px_per_ms: float


def plan(check: SceneCheck, description=None) -> Plan:
    """Build and check everything before any rendering (every error names its flag);
    ``description`` is a scene to use instead of ``check.scene``."""

    full = full_design(CaptureSpec(preset=check.preset, design=check.design))
    desc = description if description is not None else load_scene(check.scene)
    if check.speed_px_per_ms is not None:
        desc = with_speed(desc, check.speed_px_per_ms, full)
    width, height = check.width or full.width_px, check.height or full.height_px
    base = CaptureSpec(
        scene=check.scene, mode=check.mode, width=width, height=height, spp=check.spp,
        seed=check.seed, max_step_px=check.max_step_px, preset=check.preset, design=check.design,
        cover_px_per_ms=check.cover_px_per_ms, f_number=check.f_number, r_px=check.r_px,
        object_depth_mm=check.object_depth_mm, diffraction=check.diffraction,
        relative_illumination=check.relative_illumination,
    )  # fmt: skip
    cam, _ = mode_camera(capture_design(base), check.mode)
    speed = scene_speed_px_per_ms(desc, cam)
    margin = window_reach_px(cam, check.mode, 1.5 * speed, _nearest_mm(desc))
    crop = check.crop or default_window(desc, cam, margin, check.quick)
    spec = replace(base, crop=crop, spp=QUICK_SPP if check.quick else check.spp)
    padded = pad_window(crop, margin, width, height)
    truth_spec = replace(
        spec, mode="reference", crop=padded, cover_px_per_ms=None, f_number=None, r_px=None,
        diffraction="off", relative_illumination="off",  # the pinhole's radiance: the truth
    )  # fmt: skip
    check_budget(spec)
    check_budget(truth_spec, truth=True)
    offset = (crop[0] - padded[0], crop[1] - padded[1])
    return Plan(spec, truth_spec, desc, offset, margin, speed)


def _nearest_mm(desc) -> float:
    """The nearest depth of any shape's bounding box, mm (100 if none is known)."""
    zs = [float(lo[2]) for lo, _ in desc.bboxes_mm.values()]
    return min(zs) if zs else 100.0


def default_window(desc, cam, margin: int, quick: bool) -> tuple[int, int, int, int]:
    """The moving objects' t = 0 image, padded by ``margin`` and clipped to the sensor; with
    ``quick``, a small window on the fastest object's leading edge. The whole sensor for a
    scene without moving shapes of known extent."""

    boxes = {
        s: project_px(_bbox_corners(*desc.bboxes_mm[s]), cam)
        for s in desc.moving_ids
        if s in desc.bboxes_mm
    }
    W, H = cam.width_px, cam.height_px
    if not boxes:
        return (0, 0, W, H)
    if quick:
        fastest = max(boxes, key=lambda s: shape_speed_px_per_ms(desc, s, cam))
        p = boxes[fastest]
        lead = p[:, 0].max() if desc.motions[fastest].velocity_mm_per_ms[0] < 0 else p[:, 0].min()
        w, h = QUICK_WINDOW_PX
        cx, cy = int(lead), int(p[:, 1].mean())
        return _clip((cx - w // 2, cy - h // 2, w, h), W, H)
    pts = np.concatenate(list(boxes.values()))
    x0, y0 = np.floor(pts.min(0)).astype(int) - margin
    x1, y1 = np.ceil(pts.max(0)).astype(int) + margin
    box = _clip((x0, y0, x1 - x0, y1 - y0), W, H)
    if box[2] * box[3] > MAX_WINDOW_PX:
        raise ParameterError(
            f"the moving objects span a {box[2]}x{box[3]} px window, more than "
            f"{MAX_WINDOW_PX} px; give a `crop` window X,Y,W,H"
        )
    return box


def _clip(box, W: int, H: int) -> tuple[int, int, int, int]:
    x, y, w, h = (int(v) for v in box)
    w, h = min(w, W), min(h, H)
    x, y = min(max(x, 0), W - w), min(max(y, 0), H - h)
    return (x, y, w, h)


def pad_window(crop, margin: int, W: int, H: int) -> tuple[int, int, int, int]:
    """``crop`` grown by ``margin`` on every side, within the sensor."""
    x, y, w, h = crop
    x0, y0 = max(x - margin, 0), max(y - margin, 0)
    x1, y1 = min(x + w + margin, W), min(y + h + margin, H)
    return (x0, y0, x1 - x0, y1 - y0)


@dataclass
class Renders:
    """Per seed: the capture on the sharp image's scale, and the truth layers (padded)."""

    captures: list
    truths: list
    record: object
    seconds: float


def render(p: Plan, progress: bool) -> Renders:
    """The capture and the padded truth, for each of the two seeds, under one bar (each
    capture resolved once, for its estimate and its render)."""

    t0 = time.perf_counter()
    caps, truths = [], []
    runs = {}
    for seed in range(p.spec.seed, p.spec.seed + SEEDS):
        runs[f"capture (seed {seed})"] = (plan_capture(replace(p.spec, seed=seed)), False)
        runs[f"truth (seed {seed})"] = (plan_capture(replace(p.truth_spec, seed=seed)), True)
    with overall_bar(runs, "validate-scene", progress, description=p.desc) as bar:
        done = {}
        for name, (plan, truth) in runs.items():
            with bar.stage(name):
                done[name] = render_capture(plan, progress=progress, description=p.desc,
                                            truth=truth)  # fmt: skip
    for cap, ref in zip(list(done.values())[::2], list(done.values())[1::2]):
        ri_map = cap.extra_layers.get(RI_LAYER)  # irradiance -> radiance, as the model is
        caps.append(flat_field(cap.image / cap.record.light_factor, ri_map))  # white ~ 1
        truths.append(ref.extra_layers)
    return Renders(caps, truths, cap.record, time.perf_counter() - t0)


def models(p: Plan, r: Renders, quantum_px: float) -> tuple[dict, list, float]:
    """Both models for both seeds, cut to the capture's window; and the reaches."""

    cam = CameraDesign.from_inputs(r.record.camera)
    diffraction = capture_diffraction(r.record)  # the capture's: the model gets it too
    out = {name: [] for name in MODELS}
    built = []
    for truth in r.truths:
        m = convolution_model(truth["sharp"], truth, cam, p.spec.mode, quantum_px)
        built.append(m)
        for name in MODELS:
            img = getattr(m, name)
            if diffraction is not None:
                img = diffract_model(img, cam, p.spec.mode, diffraction["pixel_pitch_mm"])
            out[name].append(_inner(img, p))
    return out, built, sum(m.seconds for m in built)


def _inner(img: np.ndarray, p: Plan) -> np.ndarray:
    x, y = p.offset
    w, h = p.spec.image_size
    return img[y : y + h, x : x + w]


def regions(p: Plan, r: Renders, built: list) -> tuple[np.ndarray, np.ndarray]:
    """The region map of the capture's window (from seed S's truth and cells), and each
    pixel's signed distance to a moving edge (:func:`.scene_regions.moving_edge_distance`)."""

    cam = CameraDesign.from_inputs(r.record.camera)
    truth, cells = r.truths[0], built[0].cells
    moving = [c.reach_px for c in cells if c.moving]
    still = [c.reach_px for c in cells if not c.moving]
    beta_r = beta_px_per_mm(truth["depth"], cam) * cam.R_max_mm
    reg = region_map(
        truth["object_id"],
        beta_r,
        truth["velocity"],
        max(moving, default=0.0),
        max(still, default=0.0),
        built[0].reach_px,
    )
    dist = moving_edge_distance(truth["object_id"], beta_r, truth["velocity"])
    return _inner(reg, p), _inner(dist, p)


def settings(check: SceneCheck, p: Plan) -> dict:
    """What was validated, JSON-ready."""
    return {
        **asdict(check),
        "crop": list(p.spec.crop),
        "truth_crop": list(p.truth_spec.crop),
        "spp": p.spec.spp,
        "seeds": [p.spec.seed + k for k in range(SEEDS)],
        "margin_px": p.margin_px,
    }


def optics_settings(record) -> dict:
    """The capture's relative illumination and diffraction, as the comparison treats them."""
    ri = record.relative_illumination
    diff = (record.optics_error or {}).get("diffraction") or {}
    return {
        "relative_illumination": ri["setting"] if ri else "off",
        "flat_fielded": ri is not None,
        "diffraction": diff.get("decision", "off"),
        "model_diffracted": capture_diffraction(record) is not None,
    }


def quantum_sweep(p: Plan, r: Renders, reg: np.ndarray, quanta) -> list[dict]:
    """The model's discretisation: error against run time for each cell quantum."""
    rows = []
    for q in quanta:
        predicted, built, seconds = models(p, r, q)
        stats = {
            row["region"]: row for row in region_rows(r.captures, predicted["composite"], reg, "")
        }
        rows.append(
            {
                "quantum_px": q,
                "cells": len(built[0].cells),
                "model_s": seconds / SEEDS,
                **{
                    f"ratio_{k}": stats[k]["ratio"]
                    for k in ("moving_interior", "still_interior", "all")
                    if k in stats
                },
            }
        )
    return rows


def run(
    check: SceneCheck, out, force: bool = False, progress: bool = True, description=None
) -> dict:
    """Render, model, compare and write the report (see the module docstring).

    Parameters
    ----------
    check : SceneCheck
        The scene, its capture and the model's quantum.
    out : path-like
        The folder for the files; one that holds results is refused without ``force``.
    force : bool, optional
    progress : bool, optional
        Progress bars for the renders.
    description : SceneDescription, optional
        A scene to validate instead of ``check.scene`` (its name is kept for the report).

    Returns
    -------
    dict
        The summary: rows by model and region, the quantum sweep, timings, files written.
    """
    out_dir = prepare_out_dir(out, force)
    t0 = time.perf_counter()
    p = plan(check, description)
    r = render(p, progress)
    predicted, built, model_s = models(p, r, check.quantum_px)
    reg, dist = regions(p, r, built)
    rows = [x for name in MODELS for x in region_rows(r.captures, predicted[name], reg, name)]
    if not rows:
        raise ParameterError(
            "every pixel of the window lies within the PSFs' reach of the rendered truth's "
            "border (the sensor's edge): move or enlarge `crop`"
        )
    reach = max((c.reach_px for c in built[0].cells if c.moving), default=0.0)
    profile = [
        x
        for name in MODELS
        for x in edge_profile(r.captures, predicted[name], reg, dist, name, reach)
    ]
    quanta = (0.5, 0.25) if check.quick else QUANTA_PX
    sweep = quantum_sweep(p, r, reg, quanta)
    summary = {
        "settings": settings(check, p),
        "camera": r.record.optics,
        "optics": optics_settings(r.record),
        "speed_px_per_ms": p.speed_px_per_ms,
        "cells": len(built[0].cells),
        "reach_px": {
            "moving": reach,
            "still": max((c.reach_px for c in built[0].cells if not c.moving), default=0.0),
        },
        "rows": rows,
        "profile": profile,
        "profile_width_px": {
            name: profile_width([x for x in profile if x["model"] == name]) for name in MODELS
        },
        "sweep": sweep,
        "render_s": r.seconds,
        "model_s": model_s / SEEDS,
    }
    summary["seconds"] = time.perf_counter() - t0
    summary["files"] = scene_report.write(out_dir, summary, r, predicted, reg, force)
    return summary
