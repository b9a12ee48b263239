"""Render a light-field store: a capture's window traced once through the whole lens.

The store camera is the capture's design with its whole lens open (a static disc of radius
R_max), focused where the design focuses, on a film ``margin_px`` wider on every side. A static
scene is one render per pass, every ray at a uniform time over the exposure. A moving scene is
cut into time steps as a capture's (no more than ``max_step_px`` of image motion each, here over
the whole 45 ms, since no pattern edge is known yet); in each pass each step draws one time,
poses the geometry and gives every ray that time, so that any design's reweighted step is an
unbiased estimate of its window. Each pass draws its own times and seeds: the passes' spread is
every synthesised capture's Monte Carlo error.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from ..errors import ParameterError
from ..exposure.assemble import versions
from ..exposure.estimate import rms
from ..exposure.integrate import CaptureInterrupted
from ..exposure.plan import plan_capture
from ..exposure.render_time import Estimate, Work, rates, remember, say
from ..exposure.steps import merge_windows, plan_windows, share_spp, step_draws, step_time
from ..exposure.truth import render_truth
from ..io.arrays import read_json
from ..io.lock import output_lock
from ..io.signals import deferred_signals
from ..limits import DEFAULT_MAX_STEPS
from ..model import paper
from ..model.optics import focal_length_px
from ..render.registry import sensor_dict
from ..render.samplers import sampler_dict
from ..scenes import fastest_image_speed_px_per_ms, load_scene
from ..scenes.units import check_units
from . import geometry as geo
from .codes import design_aperture
from .proposal import Proposal, disc_plans
from .store import (
    DISK_BYTES,
    FORMAT,
    TRUTH_POSE_MS,
    Store,
    StoreSpec,
    bytes_per_sample,
    check_budget,
    load_shard,
    manifest_digest,
    planned_samples,
    save_shard,
    scene_digest,
    shard_digest,
    shard_name,
    store_digest,
    write_manifest,
)
from .target import target_spp
from .trace import Strata, trace_records

QUANTUM = 4
"""Samples per pixel of each of a moving scene's steps (as a capture's ldsampler steps): the
integrator's own dimensions are a low-discrepancy set of four per pixel. Measured on the
train (96x64 window, 256 spp): the same Monte Carlo sigma as one independent sample per step
(0.00054 both), with a quarter of the geometry updates (3.4 s against 7.7 s)."""


class StoreInterrupted(CaptureInterrupted):
    """A store stopped by a signal or ``stop_after``; its finished shards stay on disk."""


def proposal_designs(spec: StoreSpec, plan) -> list:
    """The proposal's designs as (capture plan, aperture plan, clock offset ms): the given
    ones, else the capture's design in its coded and normal modes."""

    geometric = {"diffraction": "off", "relative_illumination": "off"}
    specs = spec.designs or tuple(replace(plan.spec, mode=m) for m in ("coded", "normal"))
    out = []
    for d in specs:
        dplan = plan_capture(replace(d, **geometric)).with_diffraction(False, "proposal")
        aperture = design_aperture(dplan, dplan.sensor_params())
        out.append((dplan, aperture, aperture.t_mid - 0.5 * paper.EXPOSURE_MS))
    return out


def store_geometry(spec: StoreSpec, plan, designs: list) -> tuple[float, int]:
    """The store camera's focus (mm) and margin (px): the given ones, else the design's coded
    focus and the largest refocus of the proposal's designs (:mod:`.geometry`)."""
    design = plan.design
    focus = spec.focus_mm if spec.focus_mm is not None else design.focus_distance_mm
    if spec.margin_px is not None:
        return focus, int(spec.margin_px)
    f_px = focal_length_px(design.fov_deg, plan.spec.width)
    shears = [geo.shear_px_per_mm(f_px, focus, d.sensor_params()["focus_distance"])
              for d, _, _ in designs]  # fmt: skip
    need = [geo.margin_px(k, design.R_max_mm) for k in shears]
    return focus, max([0, *need])


def store_camera(spec: StoreSpec, plan, focus: float, m: int) -> dict:
    """The store's sensor dict and its geometry: the design's lens wide open on the enlarged
    film (same focal length in px), and what a synthesis needs to place its samples."""

    cap, design = plan.spec, plan.design
    W, H = cap.width, cap.height
    x, y, w, h = cap.crop if cap.crop else (0, 0, W, H)
    film = {"type": "hdrfilm", "width": W + 2 * m, "height": H + 2 * m,
            "rfilter": {"type": "box"}, "pixel_format": "luminance" if cap.grey else "rgb",
            "component_format": "float32", "crop_offset_x": x, "crop_offset_y": y,
            "crop_width": w + 2 * m, "crop_height": h + 2 * m}  # fmt: skip
    fov = geo.enlarged_fov_deg(W, design.fov_deg, m)
    lens = {"lens_radius": design.R_max_mm, "aperture_radius": design.R_max_mm,
            "focus_distance": focus, "schedule": "static"}  # fmt: skip
    sensor = sensor_dict(fov=fov, shutter_open=0.0, shutter_close=paper.EXPOSURE_MS,
                         reference_exposure=paper.EXPOSURE_MS, film=film,
                         sampler=sampler_dict("independent", 1), **lens)  # fmt: skip
    info = {"window": [x, y, w, h], "sensor_px": [W, H], "margin_px": m, "focus_mm": focus,
            "lens_radius_mm": design.R_max_mm, "fov_deg": design.fov_deg,
            "f_px": focal_length_px(design.fov_deg, W),
            "exposure_ms": paper.EXPOSURE_MS}  # fmt: skip
    return {"sensor": sensor, "info": info}


def plan_store_steps(spec: StoreSpec, desc, design, max_steps: int) -> list[tuple]:
    """(t0, t1, spp) per step of a pass, ms on the store's shutter clock [0, 45]."""

    E, cap = paper.EXPOSURE_MS, spec.capture
    if desc.is_static:
        return [(0.0, E, int(cap.spp))]
    speed = fastest_image_speed_px_per_ms(desc, design, (-0.5 * E, 0.5 * E))
    import numpy as np

    windows = plan_windows(np.array([0.0, E]), np.array([True]), speed, cap.max_step_px,
                           max_steps)  # fmt: skip
    windows = merge_windows(windows, max(1, int(cap.spp) // QUANTUM))  # a low spp is honoured
    shares = share_spp([b - a for _, a, b in windows], cap.spp, QUANTUM)
    return [(a, b, n) for (_, a, b), n in zip(windows, shares)]


def _store_camera_and_proposal(spec: StoreSpec, plan) -> dict:
    """The store's camera (focus and margin for its designs) with its lens proposal."""
    designs = proposal_designs(spec, plan)
    focus, margin = store_geometry(spec, plan, designs)
    cam = store_camera(spec, plan, focus, margin)
    discs = disc_plans([(a, o) for _, a, o in designs])
    cam["proposal"] = Proposal(plan.design.R_max_mm, spec.alpha, discs)
    return cam


def _check_store_budget(cam: dict, steps, cap, desc, out: Path, max_disk: int) -> None:
    """Disk and memory for the store's samples, refused with the numbers before any work."""
    window = cam["sensor"]["film"]
    pixels = window["crop_width"] * window["crop_height"]
    total, largest = planned_samples(steps, cap.passes, pixels)
    per = bytes_per_sample(1 if cap.grey else 3, desc.is_static)
    check_budget(total, largest, per, out, max_disk)


def store_work(cam: dict, steps, passes: int, out: Path) -> Work:
    """What rendering the store's shards not yet on disk takes (:class:`~pacam_render.exposure.
    render_time.Work`): one call, the first of its process (the scene, the truth layers), the
    samples traced over the film with its margin, one render per shard."""
    film = cam["sensor"]["film"]
    pixels = film["crop_width"] * film["crop_height"]
    todo = [(p, k) for p in range(passes) for k in range(len(steps))
            if not (out / shard_name(p, k)).exists()]  # fmt: skip
    samples = sum(steps[k][2] for _, k in todo) * pixels
    return Work(calls=1, first_calls=1, msamples=samples / 1e6, renders=len(todo))


def _check_least_disk(spec: StoreSpec, target, out: Path, max_disk: int) -> None:
    """Refuse a store whose fewest possible samples already exceed the disk budget, before a
    pilot, a scene or a step is planned: ``passes`` x ``spp`` (1 with a noise target, which
    plans it) x the window's pixels (the margin only adds), without per-sample times."""
    cap = spec.capture
    _, _, w, h = cap.crop if cap.crop else (0, 0, cap.width, cap.height)
    spp = 1 if target is not None else int(cap.spp)
    per = bytes_per_sample(1 if cap.grey else 3, False)
    check_budget(int(cap.passes) * spp * w * h, 0, per, out, max_disk)


def _planned(spec: StoreSpec, target, progress: bool, description):
    """``spec`` at the spp a noise target plans (:func:`~.target.target_spp`), and the plan
    for the manifest; ``spec`` and None without a target."""
    if target is None:
        return spec, None

    spp, rows = target_spp(render_lightfield, spec, target, progress, description, QUANTUM)
    spec = replace(spec, capture=replace(spec.capture, spp=spp))
    return spec, {"target": target.to_json(), "spp": spp, "designs": rows}


def render_lightfield(
    spec: StoreSpec,
    out,
    progress: bool = True,
    max_steps: int = DEFAULT_MAX_STEPS,
    max_disk: int = DISK_BYTES,
    stop_after: int | None = None,
    truth: bool = True,
    description=None,
    target=None,
) -> Store:
    """Render a store into folder ``out`` (module docstring), resuming the shards on disk.

    Parameters
    ----------
    spec : StoreSpec
        What to render.
    out : path-like
        The store's folder (created; locked while the store renders).
    progress : bool, optional
        A progress bar over the shards.
    max_steps : int, optional
        The most time steps a pass may take (``max_steps``).
    max_disk : int, optional
        The most bytes the store may take on disk (default 20 GiB).
    stop_after : int, optional
        Stop after this many new shards (:class:`StoreInterrupted`), as a signal would.
    truth : bool, optional
        Also render the ground-truth layers (``sharp``, ``depth``, ``object_id``,
        ``velocity``) of the capture's window, once.
    description : SceneDescription, optional
        A scene to render instead of ``spec.capture.scene`` (its digest is recorded).
    target : NoiseTarget, optional
        Render as many samples as bring every design the store is made for to this Monte
        Carlo sigma, planned from a pilot store (:func:`~.target.target_spp`); replaces
        ``spec.capture.spp``, and the store's manifest records the plan.

    Returns
    -------
    Store

    Raises
    ------
    ParameterError
        If the samples exceed the disk or memory budget (before any work), or ``out`` holds a
        store of another spec.
    StoreInterrupted
        On SIGINT or SIGTERM, or after ``stop_after`` shards; the finished shards are kept.
    """

    out = Path(out)
    _check_least_disk(spec, target, out, max_disk)
    spec, planned = _planned(spec, target, progress, description)
    cap = replace(spec.capture, mode="coded", diffraction="off", relative_illumination="off")
    plan = plan_capture(cap)
    cam = _store_camera_and_proposal(spec, plan)
    desc = description if description is not None else load_scene(cap.scene)
    steps = plan_store_steps(spec, desc, plan.design, max_steps)
    _check_store_budget(cam, steps, cap, desc, out, max_disk)
    key, work = f"lightfield {plan.variant}", store_work(cam, steps, cap.passes, out)
    if progress:
        say(f"estimate: {Estimate({'store': work}, rates(key)).describe()}")
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    with output_lock(out), deferred_signals() as flag:
        manifest = _manifest(spec, plan, cam, steps, out, scene_digest(desc))
        digests = _render_shards(spec, plan, cam, desc, steps, out, manifest, flag, progress,
                                 stop_after)  # fmt: skip
        if truth and not _truth_current(out / "truth.npz", desc):
            _render_truth(cap, plan, cam, desc, out)
        remember(key, work, time.perf_counter() - t_start)
        _complete(manifest, spec, out, digests, planned)
    return Store.open(out)


def _complete(manifest: dict, spec: StoreSpec, out: Path, digests, planned) -> None:
    """Write the finished store's manifest: complete, the store's and every shard's digest,
    the truth layers' digest, the noise target's plan, and the manifest's own digest."""
    manifest.update(complete=True, digest=store_digest(spec.key(), digests))
    if planned is not None:
        manifest["noise_target"] = planned
    manifest["shard_digests"] = digests
    truth = out / "truth.npz"
    manifest["truth_digest"] = shard_digest(*load_shard(truth)) if truth.exists() else None
    manifest["seconds"] = round(manifest.get("seconds", 0.0), 3)
    manifest["manifest_digest"] = manifest_digest(manifest)
    write_manifest(out, manifest)


def _manifest(spec: StoreSpec, plan, cam: dict, steps, out: Path, scene_digest: str) -> dict:
    """The store's manifest: a new one, or the one on disk when it is this spec's (resume)."""

    path = out / "store.json"
    if path.is_file():
        old = read_json(path, "the store's manifest")
        if not isinstance(old, dict) or old.get("key") != spec.key():
            key = old.get("key") if isinstance(old, dict) else None
            raise ParameterError(
                f"{out} holds a light-field store of another spec (key {key}, this "
                f"one {spec.key()}); choose another `out`, or remove it"
            )
        return old
    manifest = {
        "format": FORMAT, "key": spec.key(), "spec": spec.to_json(), "complete": False,
        "camera": cam["info"], "design": plan.design.inputs(), "variant": plan.variant,
        "versions": versions(), "scene": plan.spec.scene, "scene_digest": scene_digest,
        "channels": 1 if plan.spec.grey else 3, "passes": plan.spec.passes,
        "steps": [[list(s) for s in steps] for _ in range(plan.spec.passes)],
        "mid_ms": 0.5 * paper.EXPOSURE_MS, "seconds": 0.0,
        "proposal": cam["proposal"].to_json(),
        "sampling": "per pixel, a Latin hypercube over each pass's samples (film and lens)"
        if Strata.fits(cam["sensor"]["film"]["crop_width"] * cam["sensor"]["film"]["crop_height"],
                       sum(s[2] for s in steps)) else "independent",
    }  # fmt: skip
    write_manifest(out, manifest)
    return manifest


def _render_shards(spec, plan, cam, desc, steps, out, manifest, flag, progress, stop_after):
    """Every shard not yet on disk; returns each shard's digest, pass by pass."""
    from tqdm import tqdm

    scene = desc.load(sensor=cam["sensor"])
    sensor = scene.sensors()[0]
    check_units(scene, plan.design)
    animator = None if desc.is_static else desc.animator(scene)
    film = cam["sensor"]["film"]
    window = (film["crop_offset_x"], film["crop_offset_y"], film["crop_width"],
              film["crop_height"])  # fmt: skip
    m, cap = cam["info"]["margin_px"], plan.spec
    digests, new = [], 0
    bar = tqdm(total=cap.passes * len(steps), desc=f"light field {cap.scene}", disable=not progress)
    pixels = window[2] * window[3]
    per_pass = sum(s[2] for s in steps)
    try:
        for p in range(cap.passes):
            row, first = [], 0
            strata = (
                Strata(pixels, per_pass, cap.seed, p) if Strata.fits(pixels, per_pass) else None
            )
            for k, (t0, t1, spp) in enumerate(steps):
                first, k0 = first + spp, first
                name = shard_name(p, k)
                if (out / name).exists():
                    row.append(shard_digest(*load_shard(out / name)))
                    bar.update()
                    continue
                seed, u = step_draws(cap.seed, p, k)
                t_start = time.perf_counter()
                if animator is None:
                    times = (t0, t1)
                else:
                    times = step_time(t0, t1, u)
                    animator.set_time(times - manifest["mid_ms"])
                rec = _records(scene, sensor, window, spp, seed, times, cam, m,
                               None if strata is None else (strata, k0))  # fmt: skip
                meta = {"t0": t0, "t1": t1, "spp": spp, "time": None if animator is None else times}
                row.append(save_shard(out, name, rec, meta))
                manifest["seconds"] = manifest.get("seconds", 0.0) + time.perf_counter() - t_start
                bar.update()
                new += 1
                if flag["signal"] is not None or (stop_after is not None and new >= stop_after):
                    write_manifest(out, manifest)
                    raise StoreInterrupted(
                        f"the store stopped after {new} new shard(s); they are saved in {out}: run "
                        "the same command again to resume",
                        signum=flag["signal"],
                    )
            digests.append(row)
            write_manifest(out, manifest)
    finally:
        bar.close()
        if animator is not None:  # back to t = 0, as after a direct capture: the
            animator.set_time(0.0)  # description's meshes are shared with the truth's scene
    return digests


def _records(scene, sensor, window, spp, seed, times, cam, margin, strata) -> dict:
    """One step's records, film points in px of the capture's sensor (the margin taken off)."""

    rec = trace_records(scene, sensor, window, spp, seed, times, cam["proposal"], strata)
    rec["x"] += float(window[0] - margin)  # the crop's corner, in px of the enlarged film
    rec["y"] += float(window[1] - margin)
    return rec


def _truth_current(path: Path, desc) -> bool:
    """Whether ``truth.npz`` is there and shows the scene at t = 0 (:data:`TRUTH_POSE_MS`; a
    moving scene's truth that does not record its pose is rendered again)."""
    if not path.exists():
        return False
    return desc.is_static or load_shard(path)[1].get("pose_ms") == TRUTH_POSE_MS


def _render_truth(cap, plan, cam: dict, desc, out: Path) -> None:
    """The capture window's ground-truth layers, rendered once (the scene at t = 0; the
    layers' own pinhole sensors are :func:`~pacam_render.exposure.truth.render_truth`'s)."""

    scene = desc.load(sensor=cam["sensor"])
    layers, objects, sharp = render_truth(scene, desc, cap, plan.design, True, None, None)
    meta = {"objects": objects, "sharp_mc_sigma": None if sharp is None else rms(sharp.variance()),
            "pose_ms": TRUTH_POSE_MS}  # fmt: skip
    save_shard(out, "truth.npz", dict(layers), meta)
