"""One task of a study: render a capture with its ground truth once, then for each of its points
apply the sensor, deconvolve and score. Runs the same in-process or on a Dask worker.

A point's result depends only on its own values and seed: the render is bit-identical for a
seed (:mod:`pacam_render.render.passes`), and the sensor's noise is drawn from the point's seed.
"""

from __future__ import annotations

import time
import traceback
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exposure.camera import full_design
from ..exposure.direct import CaptureInterrupted, render_capture
from ..exposure.spec import GEOMETRIC_OPTICS, CaptureSpec
from ..io.exr import write_exr
from ..io.outputs import write_json
from ..limits import PacamWarning
from ..restore.capture_deblur import deblur_input
from ..restore.capture_score import edge_px_of, flat_sigma, kernel, radiance
from ..restore.deconvolve import deconvolve, nonnegative_for
from ..restore.metrics import shift_search_px
from ..restore.model_error import model_sigma
from ..restore.object_score import score, shift_bounds
from ..scenes import load_scene
from ..scenes.edit import at_depth, moving_depth_mm, scene_speed_px_per_ms, with_speed
from ..sensor.apply import SensorTarget, add_sensor_layers
from ..sensor.model import SensorModel
from .plateau import decompose
from .spec import Point, parse_design, target_sensors

COLUMNS = (
    "point", "scene", "mode", "design", "speed_px_per_ms", "depth_mm",
    "light_level_photons_per_px_per_ms", "sensor", "method", "seed",
    "psnr_db", "ssim", "psnr_moving_db", "psnr_static_db", "psnr_moving_interior_db",
    "psnr_by_object",
    "r_px", "a_i_px_per_ms2", "velocity_range_px_per_ms", "exposure_ms", "light_factor",
    "noise_sigma", "render_noise_sigma", "render_noise_ratio", "sharp_noise_sigma",
    "model_sigma", "deconv_sigma", "model_error", "render_spp", "psnr_moving_no_model_sigma_db",
    "psnr_moving_floor_db", "psnr_moving_exact_model_db", "psnr_moving_oracle_db",
    "render_s", "total_s", "status",
    "diffraction", "diffraction_sigma", "optics_left_out", "optics_left_out_sigma",
    "point_key", "row_digest",
)  # fmt: skip
"""The columns of ``results.csv``, in order. Speeds are in the preset's own pixels (px/ms of
the full sensor); r, a_i and the invariant range are the capture camera's at the study's
resolution. Noise, white = 1: ``noise_sigma`` is the sensor's, ``render_noise_sigma`` the
render's measured Monte Carlo sigma (``render_error.mc_sigma``) and ``render_noise_ratio``
the one over the other, ``sharp_noise_sigma`` the truth's own, ``model_sigma`` the capture's
measured departure from its deconvolver's model (:mod:`~pacam_render.restore.model_error`),
and ``deconv_sigma``
the root sum of squares of what the deconvolver is told: the sensor's and the render's noise,
and the model error only where ``model_error`` says (``none``, the default: what a real user
knows; ``oracle``: the scored capture's own ``model_sigma``, measured against its ``sharp``
layer; ``given S``: a model sigma calibrated on another capture; a row without it was written
before the choice, with the oracle; :mod:`~pacam_render.restore.capture_deblur`). Restored as
``pacam deconvolve`` restores (the sensor's noise per pixel for ``hl`` and ``tv``).
``render_spp`` and
``render_s`` are the shared render of the point's group. The ``psnr_moving_*_db`` columns
after it decompose the score (:mod:`.plateau`; with ``[study] decompose = true``), the last,
``psnr_moving_oracle_db``, told the capture's own model error (the oracle's score).
The optics (``capture.json``'s ``optics_error``, white = 1): ``diffraction`` is ``in`` or
``out`` of the capture, ``diffraction_sigma`` its measured effect where it is left out, and
``optics_left_out`` / ``optics_left_out_sigma`` the largest left-out effect and its size
(:data:`LATE_COLUMNS`: rows written before them lack them, and stay intact).
``point_key`` is the point's :meth:`~pacam_render.study.spec.StudySpec.point_keys`: a resume
keeps a row whose key a point of the new spec has."""
OPTICS_COLUMNS = ("diffraction", "diffraction_sigma", "optics_left_out", "optics_left_out_sigma")
"""The optics columns (:func:`optics_columns`)."""
LATE_COLUMNS = (*OPTICS_COLUMNS, "model_error", "psnr_moving_oracle_db")
"""Columns that older results.csv files lack (:func:`~.results.row_digest` skips them there)."""


@dataclass(frozen=True)
class Task:
    """A render and the points scored on it; ``partial_dir`` keeps the render's finished
    passes (its pilot's, and an interrupted render's), so that a re-run resumes them.
    ``group`` is every point of the render, done or not (default ``points``): its noise
    target is theirs, so a render for the points still to do is the one a fresh run makes."""

    render: dict
    points: tuple[Point, ...]
    keep_dir: str | None = None
    partial_dir: str | None = None
    decompose: bool = False
    group: tuple[Point, ...] = ()
    model_error: str | float = "none"
    """What the deconvolver is told of the model error (:data:`~pacam_render.restore.
    capture_deblur.MODEL_ERRORS`, or a calibrated sigma)."""


def run_task(task: Task) -> list[dict]:
    """Render ``task``'s capture, then score each point; errors become the points' status.

    Returns
    -------
    list of dict
        One row per point, keyed by :data:`COLUMNS`; ``status`` is ``ok`` or ``error: ...``.
    """

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)  # notes stay in the capture's record
        try:
            cap, desc, info = _render(task)
        except CaptureInterrupted:  # Ctrl-C in a serial run stops the study, not the point
            raise
        except Exception as exc:  # a point that cannot render is reported, the study goes on
            return error_rows(task.points, exc, time.perf_counter() - t0)
        render_s = time.perf_counter() - t0
        return score_points(cap, desc, info, task, task.points, render_s)


def score_points(cap, desc, info: dict, task: Task, points, render_s: float) -> list[dict]:
    """One row per point on one capture: its sensor, deconvolution and scores."""
    rows = []
    for p in points:
        t1 = time.perf_counter()
        try:
            values, status = {**info, **_evaluate(cap, desc, p, task, info)}, "ok"
        except Exception as exc:
            values, status = info, _status(exc)
        rows.append(point_row(p, values, status, render_s, render_s + time.perf_counter() - t1))
    return rows


def error_rows(points, exc: Exception, seconds: float) -> list[dict]:
    """The rows of points whose capture failed: the error in each one's status."""
    return [point_row(p, {}, _status(exc), 0.0, seconds) for p in points]


def _status(exc: Exception) -> str:
    where = traceback.extract_tb(exc.__traceback__)[-1]
    return f"error: {type(exc).__name__}: {exc} ({Path(where.filename).name}:{where.lineno})"


def capture_inputs(render: dict, p: Point):
    """The CaptureSpec and scene description of a point (its speed and depth applied)."""

    spec = CaptureSpec(
        scene=p.scene,
        mode=p.mode,
        width=render["width"],
        height=render["height"],
        crop=tuple(render["crop"]) if render["crop"] else None,
        spp=render["spp"],
        sampler=render.get("sampler", "ldsampler"),
        seed=p.seed,
        max_step_px=render["max_step_px"],
        preset=render["preset"],
        object_depth_mm=render["object_depth_mm"],
        grey=bool(render.get("grey", False)),
        diffraction=render.get("diffraction", GEOMETRIC_OPTICS["diffraction"]),
        relative_illumination=render.get(
            "relative_illumination", GEOMETRIC_OPTICS["relative_illumination"]
        ),
        **parse_design(p.design),
    )
    full = full_design(spec)  # speeds are in the design's own (full sensor) pixels
    desc = load_scene(p.scene)
    if p.depth_mm is not None:
        desc = at_depth(desc, p.depth_mm, full)
    if p.speed_px_per_ms is not None:
        desc = with_speed(desc, p.speed_px_per_ms, full)
    info = {"speed_px_per_ms": scene_speed_px_per_ms(desc, full)}
    return spec, desc, {**info, "depth_mm": moving_depth_mm(desc, full)}


def _render(task: Task):

    spec, desc, info = capture_inputs(task.render, task.points[0])
    target = render_target(task.render, task.group or task.points)
    cap = render_capture(
        spec, _partial(task), progress=False, description=desc, truth=True, target=target
    )
    return cap, desc, capture_info(cap, desc, info)


def capture_info(cap, desc, info: dict) -> dict:
    """A rendered (or synthesised) capture's columns: its camera, scale, errors and optics."""
    info = dict(info)
    rec = cap.record
    optics = rec.optics
    info.update({k: optics[k] for k in ("r_px", "a_i_px_per_ms2", "velocity_range_px_per_ms")})
    info.update(exposure_ms=rec.exposure_ms, light_factor=rec.light_factor)
    err = rec.render_error
    info.update(
        render_noise_sigma=flat_sigma(cap, err.mc_sigma_white_units),
        sharp_noise_sigma=err.sharp_mc_sigma,
        render_spp=err.spp,
    )
    info["model_sigma"] = _model_sigma(cap, desc)
    info.update(optics_columns(rec.optics_error, rec.light_factor))
    return info


def optics_columns(block: dict | None, light_factor: float) -> dict:
    """The :data:`OPTICS_COLUMNS` of a capture's ``optics_error``, white = 1."""
    if not block or light_factor <= 0:
        return {}
    effects = block["effects"]
    diff = effects["diffraction"]
    worst = block.get("largest_left_out")
    size = effects[worst]["size_rms"] if worst else None
    return {
        "diffraction": "in" if diff["included"] else "out",
        "diffraction_sigma": None if diff["size_rms"] is None else diff["size_rms"] / light_factor,
        "optics_left_out": worst,
        "optics_left_out_sigma": None if size is None else size / light_factor,
    }


def pilot_task(task: Task) -> dict:
    """The pilot passes of a task's render, kept in its ``partial_dir`` for the render to
    resume from, and what they predict: ``seconds`` (the pilot's), ``predicted_seconds`` (the
    rest of the render's passes), ``pilot_spp`` and ``planned_spp`` (what the target needs)."""
    import warnings

    spec, desc, _ = capture_inputs(task.render, task.points[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PacamWarning)
        cap = render_capture(
            spec,
            _partial(task),
            progress=False,
            description=desc,
            truth=False,
            target=render_target(task.render, task.group or task.points),
            pilot_only=True,
        )
    err = cap.record.render_error
    return {
        "seconds": err.seconds,
        "predicted_seconds": err.predicted_seconds or 0.0,
        "pilot_spp": err.spp,
        "planned_spp": err.planned_spp,
    }


def _partial(task: Task) -> Path | None:
    return None if task.partial_dir is None else Path(task.partial_dir)


def render_target(render: dict, points):
    """The noise target of a render that feeds ``points``: ``noise_ratio`` times the lowest of
    their sensors' noises (:class:`~pacam_render.sensor.apply.SensorTarget`), or None."""
    if render.get("noise_ratio") is None:
        return None

    return SensorTarget(float(render["noise_ratio"]), target_sensors(points))


def _model_sigma(cap, desc) -> float:
    """The capture's departure from its deconvolver's model, white = 1
    (:mod:`~pacam_render.restore.model_error`)."""

    layers = cap.extra_layers
    sharp_var = (cap.record.render_error.sharp_mc_sigma or 0.0) ** 2
    return model_sigma(
        radiance(cap, cap.image),
        layers["sharp"],
        kernel(cap),
        layers["object_id"],
        cap.record.objects,
        set(desc.moving_ids),
        shift_search_px(cap.record.spec["width"]),
        radiance(cap, cap.mc_sigma) ** 2,  # the per-pixel sigma, flat-fielded alike
        sharp_var,
    )


def _evaluate(cap, desc, p: Point, task: Task, info: dict) -> dict:
    """Sensor, deconvolution and scores of one point on the rendered capture, restored as
    ``pacam deconvolve`` restores it (:func:`_restore`)."""

    add_sensor_layers(cap, SensorModel.from_preset(p.sensor), p.sensor, p.light_level, p.seed)
    told = told_model_sigma(task.model_error, info["model_sigma"])
    est = _restore(cap, p.method, told)
    if task.keep_dir is not None:
        _keep(cap, est, p, Path(task.keep_dir))
    shift = shift_search_px(cap.record.spec["width"])
    edge = edge_px_of(cap)
    objects, moving = cap.record.objects, set(desc.moving_ids)
    bounds = shift_bounds(cap.extra_layers, objects, moving, cap.record, shift)

    def scorer(image):
        return score(image, cap.extra_layers, objects, moving, shift, edge, bounds)

    out = scorer(est)
    sigma = flat_sigma(cap, cap.record.noise_sigma_white_units)
    parts = (sigma, info["render_noise_sigma"], told or 0.0)
    if task.decompose:
        noisy = radiance(cap, cap.extra_layers["noisy"])  # white reads ~ its reflectance
        clean = radiance(cap, cap.image)
        out.update(decompose(cap, kernel(cap), p.method, noisy, parts, scorer, clean))
    out.update(_model_error_scores(cap, p.method, task, info["model_sigma"], told, scorer, out))
    ratio = info["render_noise_sigma"] / sigma if sigma > 0 else float("inf")
    total = float(np.sqrt(sum(x * x for x in parts)))
    return {**out, "noise_sigma": sigma, "render_noise_ratio": ratio, "deconv_sigma": total,
            "model_error": model_error_label(task.model_error)}  # fmt: skip


def _model_error_scores(cap, method, task, measured, told, scorer, out) -> dict:
    """The moving objects' PSNR told no model error (``psnr_moving_no_model_sigma_db``), and
    told the capture's own measured one (``psnr_moving_oracle_db``, the oracle's score:
    with ``decompose``, or when the study is the oracle's); each restored afresh only when
    the study's own restoration is not already it."""

    def moving(sigma):
        return scorer(_restore(cap, method, sigma))["psnr_moving_db"]

    extra = {"psnr_moving_no_model_sigma_db": moving(None) if told else out["psnr_moving_db"]}
    if task.model_error == "oracle":
        extra["psnr_moving_oracle_db"] = out["psnr_moving_db"]
    elif task.decompose and measured > 0:
        extra["psnr_moving_oracle_db"] = moving(measured)
    return extra


def told_model_sigma(model_error, measured: float) -> float | None:
    """The model sigma the deconvolver is told (white = 1): None for ``none``, the scored
    capture's own ``measured`` one for ``oracle``, else the calibrated value given."""
    if model_error == "none":
        return None
    return float(measured) if model_error == "oracle" else float(model_error)


def model_error_label(model_error) -> str:
    """The ``model_error`` column: ``none``, ``oracle`` or ``given S``."""
    return model_error if isinstance(model_error, str) else f"given {float(model_error):.4g}"


def _restore(cap, method: str, model_sigma: float | None) -> np.ndarray:
    """The sensor layer ``noisy`` restored as ``pacam deconvolve`` does (the deconvolver told
    the sensor's and the render's noise, and ``model_sigma`` when given:
    :func:`~pacam_render.restore.capture_deblur.deblur_input`), white = 1."""

    layers = {**cap.extra_layers, "capture": cap.image}
    d = deblur_input(layers, "noisy", cap.record, method, model_sigma=model_sigma)
    if method != "none":
        d.image = deconvolve(nonnegative_for(method, d.image)[0], kernel(cap), method, **d.kw)
    return d.image / cap.record.light_factor


def _keep(cap, est, p: Point, folder: Path) -> None:

    folder.mkdir(parents=True, exist_ok=True)
    layers = {"estimate": est, "noisy": cap.extra_layers["noisy"], "capture": cap.image}
    layers.update({k: cap.extra_layers[k] for k in ("sharp", "depth", "object_id", "velocity")})
    write_exr(folder / f"point_{p.index:05d}.exr", layers, force=True)
    write_json(folder / f"point_{p.index:05d}.json", cap.record.to_json(), force=True)


def point_row(p: Point, values: dict, status: str, render_s: float, total_s: float) -> dict:
    row = {c: "" for c in COLUMNS}
    row.update(
        point=p.index,
        scene=p.scene,
        mode=p.mode,
        design=p.design,
        speed_px_per_ms=p.speed_px_per_ms,
        depth_mm=p.depth_mm,
        light_level_photons_per_px_per_ms=p.light_level,
        sensor=p.sensor,
        method=p.method,
        seed=p.seed,
    )
    row.update({k: _short(v) for k, v in values.items() if k in row and v is not None})
    row.update(render_s=round(render_s, 3), total_s=round(total_s, 3), status=status)
    return row


def _short(v):
    """Floats to 7 significant digits: the CSV stays readable, and far finer than any score."""
    return float(f"{v:.7g}") if isinstance(v, float) else v
