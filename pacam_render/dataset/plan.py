"""A dataset's samples: scenes x cameras x light levels, each with a key, and the work's bounds.

A *render* is one scene through one camera; its capture goes through the image sensor once per
light level, and each light level is a *sample*. A sample's key is a digest of everything that
determines its files (the capture's :meth:`~pacam_render.exposure.spec.CaptureSpec.key`, the
scene file's bytes, the sensor, the light level, the seeds, the PSF's speed), so that a sample
whose folder holds its key is done. Seeds are derived from the spec's ``seed`` and the key
without it: the same spec gives the same dataset, and no two renders share a seed by accident.

Disk is estimated per sample (:func:`sample_bytes`) and refused over ``[run] max_disk_gib`` or
the free disk, and memory per render (:func:`~pacam_render.exposure.direct.check_budget`),
before any work.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import ParameterError
from ..exposure.direct import check_budget
from ..exposure.plan import plan_capture
from ..exposure.spec import CaptureSpec
from ..lightfield.codes import SERVED, check_served
from ..limits import DEFAULT_MAX_SAMPLES, free_disk, gib
from ..model.modes import MODES, MODES_WITH_PSF
from ..psf.analytic import least_lost_fraction
from .spec import DatasetSpec

FORMAT_VERSION = 1
"""The layout of a sample's folder; in every key, so a new layout renders afresh."""

LAYER_CHANNELS = {"capture": "c", "sharp": "c", "noisy": "c", "depth": 1, "object_id": 1,
                  "raw": 1, "relative_illumination": 1, "velocity": 2}  # fmt: skip
"""The layers of a sample's capture.exr and their channels (``c``: 3, or 1 when grey)."""

SIDECAR_BYTES = 64 * 1024
"""A bound on a sample's JSON files (capture.json about 10 KiB, psf.json, sample.json)."""


@dataclass(frozen=True)
class PlannedSample:
    """One sample: its id (the folder's name), key, light level and sensor seed."""

    id: str
    key: str
    scene: str
    camera: str
    light_level: float
    sensor_seed: int


@dataclass(frozen=True)
class Render:
    """One scene through one camera (its spec, seed derived), and the samples it makes."""

    scene: str
    scene_label: str
    camera: str
    spec: CaptureSpec
    samples: tuple[PlannedSample, ...]
    via: str = "direct"
    """``direct`` (its own render) or ``store`` (synthesised from its scene's light-field
    store, :func:`use_store`)."""


@dataclass(frozen=True)
class DatasetPlan:
    """Every render and sample of a spec, with the disk they take (bytes, an upper bound)."""

    spec: DatasetSpec
    renders: tuple[Render, ...]
    bytes_per_sample: dict
    """Camera name -> bytes of one sample's files."""

    @property
    def samples(self) -> list[PlannedSample]:
        return [s for r in self.renders for s in r.samples]

    @property
    def disk_bytes(self) -> int:
        return sum(self.bytes_per_sample[r.camera] * len(r.samples) for r in self.renders)


def derived_seed(seed: int, text: str) -> int:
    """A seed in [0, 2^31) from the spec's ``seed`` and ``text`` (a key without seeds)."""
    h = hashlib.sha256(f"{seed}:{text}".encode()).digest()
    return int.from_bytes(h[:4], "little") & 0x7FFFFFFF


def scene_digest(scene: str, spec: DatasetSpec) -> str:
    """What identifies a scene's content: a file scene's bytes (and its motion sidecar), a
    family seed's name and parameters, a built-in scene's name."""
    h = hashlib.sha256(scene.encode())
    if scene.startswith("family:"):
        h.update(json.dumps(spec.family_params or {}, sort_keys=True).encode())
        return h.hexdigest()[:16]
    path = Path(scene)
    for p in (path, path.with_suffix(".motion.json")):
        if p.is_file():
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def scene_label(scene: str, index: int) -> str:
    """A short, unique label for sample ids: ``occluders-12``, ``train``, ``0001-my_scene``."""
    if scene.startswith("family:"):
        _, family, seed = scene.split(":")
        return f"{family}-{seed}"
    if "/" not in scene and "." not in scene:
        return scene
    return f"{index:04d}-{Path(scene).stem}"


def plan_dataset(spec: DatasetSpec) -> DatasetPlan:
    """The spec's renders and samples, refused over the disk or memory bounds.

    Parameters
    ----------
    spec : DatasetSpec
        The dataset.

    Raises
    ------
    ParameterError
        If the samples' files exceed ``[run] max_disk_gib``, or one render's
        memory or samples the machine's (naming the keys that lower them).
    """
    target = _target_json(spec)
    renders = []
    stores = use_store(spec)  # a camera's servability is its own, not its scene's: once each
    via = {c.name: "store" if stores and store_serves(_base_spec(spec, "train", c)) else "direct"
           for c in spec.cameras}  # fmt: skip
    for i, scene in enumerate(spec.scenes):
        digest, label = scene_digest(scene, spec), scene_label(scene, i)
        for cam in spec.cameras:
            renders.append(_render(spec, scene, label, digest, cam, target, via[cam.name]))
    v = spec.psf_velocity_px_per_ms
    sizes = {c.name: sample_bytes(_base_spec(spec, "train", c), v) for c in spec.cameras}
    plan = DatasetPlan(spec, tuple(renders), sizes)
    check_disk(plan.disk_bytes, spec.max_disk_gib, None)
    for cam in spec.cameras:
        check_budget(_base_spec(spec, "train", cam), spec.max_samples or DEFAULT_MAX_SAMPLES,
                     True, target is not None)  # fmt: skip
    return plan


def _target_json(spec: DatasetSpec) -> dict | None:
    if spec.noise_ratio is not None:
        return {"ratio": spec.noise_ratio, "sensor": spec.sensor, "levels": spec.light_levels}
    if spec.noise_target is not None:
        return {"sigma": spec.noise_target}
    return None


def _base_spec(spec: DatasetSpec, scene: str, cam) -> CaptureSpec:
    return CaptureSpec(scene=scene, **spec.capture, **cam.fields)


def _render(
    spec: DatasetSpec, scene: str, label: str, digest: str, cam, target, via: str = "direct"
) -> Render:
    """One render of ``scene`` by ``cam``: its seed derived, and a sample per light level. A
    store's captures take the store's seed (its scene's), so their keys name the store."""
    base = _base_spec(spec, scene, cam)
    unseeded = f"{base.key()}:{digest}:{json.dumps(target, sort_keys=True)}"
    if via == "store":
        unseeded = f"store:{digest}:{json.dumps(target, sort_keys=True)}"
    cap = replace(base, seed=derived_seed(spec.seed, unseeded))
    render_key = f"{cap.key()}:{digest}:{json.dumps(target, sort_keys=True)}:{via}"
    if via == "store":  # the store's samples are shared by the scene's cameras
        render_key += ":" + ":".join(_base_spec(spec, scene, c).key() for c in spec.cameras)
    samples = []
    for level in spec.light_levels:
        what = {"render": render_key, "sensor": spec.sensor,
                "sensor_file": _file_digest(spec.sensor), "light": level,
                "psf_velocity": spec.psf_velocity_px_per_ms, "format": FORMAT_VERSION}  # fmt: skip
        text = json.dumps(what, sort_keys=True)
        seed = derived_seed(spec.seed, "sensor:" + text)
        key = hashlib.sha256(f"{text}:{seed}".encode()).hexdigest()[:16]
        sid = f"{label}_{cam.name}_L{level:g}"
        samples.append(PlannedSample(sid, key, scene, cam.name, level, seed))
    return Render(scene, label, cam.name, cap, tuple(samples), via)


def _file_digest(name: str) -> str | None:
    p = Path(name)
    return hashlib.sha256(p.read_bytes()).hexdigest()[:16] if p.is_file() else None


def sample_bytes(spec: CaptureSpec, velocity_px_per_ms: float = 0.0) -> int:
    """An upper bound on one sample's files, bytes: capture.exr uncompressed (float32,
    :data:`LAYER_CHANNELS`), its PNG preview (8-bit RGB), the PSF (float32 EXR and an 8-bit
    PNG of the kernel's automatic size), and :data:`SIDECAR_BYTES`."""
    w, h = spec.image_size
    c = 1 if spec.grey else 3
    channels = sum(c if n == "c" else n for n in LAYER_CHANNELS.values())
    exr, png = 4 * channels * w * h, 3 * w * h
    psf = 0
    if spec.mode in MODES_WITH_PSF:
        cam = plan_capture(spec).cam
        _, (kh, kw), _ = least_lost_fraction(cam, spec.mode, velocity_px_per_ms, None, "pinhole")
        psf = (4 + 3) * kh * kw
    return exr + png + psf + SIDECAR_BYTES


def check_disk(nbytes: int, max_disk_gib: float, out: Path | None) -> None:
    """Refuse ``nbytes`` over ``max_disk_gib`` GiB or the free disk under ``out``.

    Raises
    ------
    ParameterError
        Naming ``[run] max_disk_gib``, or the free space.
    """
    limit = max_disk_gib * 2**30
    if nbytes > limit:
        raise ParameterError(
            f"the samples need about {gib(nbytes)} of disk, above [run] max_disk_gib "
            f"{max_disk_gib:g} GiB; raise it, or ask for fewer scenes, cameras, light levels or "
            "a smaller [capture] window"
        )
    if out is None:
        return
    where, free = free_disk(out)
    if nbytes > free:
        raise ParameterError(
            f"the samples need about {gib(nbytes)} of disk, and {gib(free)} is free at {where}"
        )


STORE_RATIOS = ((1, 9.909), (4, 2.638), (16, 0.8173), (64, 0.362))
"""(designs N, wall time of one light-field store + N syntheses / N direct renders), to the
same Monte Carlo sigma: measured in ``benchmarks/RESULTS.md``, "Light-field store: wall time to
one Monte Carlo sigma, N covering designs" (``python benchmarks/bench_lightfield.py``, a moving
96x64 train window, 2 cores, 2026-11-28)."""


def store_ratio(n_cameras: int) -> float:
    """One store and ``n_cameras`` syntheses over ``n_cameras`` direct renders, in wall time
    (:data:`STORE_RATIOS`, interpolated linearly in log N and log ratio, extrapolated at the
    ends)."""
    pts = [(math.log(n), math.log(r)) for n, r in STORE_RATIOS]
    x = math.log(max(1, n_cameras))
    i = min(max(0, sum(x > p[0] for p in pts) - 1), len(pts) - 2)
    (x0, y0), (x1, y1) = pts[i], pts[i + 1]
    return math.exp(y0 + (y1 - y0) * (x - x0) / (x1 - x0))


def break_even_cameras() -> float:
    """The cameras per scene above which a store costs less than direct renders: where
    :data:`STORE_RATIOS` crosses 1, interpolated linearly in log N and log ratio (about 12.6)."""
    pts = [(math.log(n), math.log(r)) for n, r in STORE_RATIOS]
    for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
        if y0 >= 0.0 > y1:
            return math.exp(x0 + (x1 - x0) * y0 / (y0 - y1))
    return math.inf


def use_store(spec: DatasetSpec) -> bool:
    """Whether a scene's cameras are synthesised from one light-field store: ``[run] store``
    ``always``, or ``auto`` above :func:`break_even_cameras` cameras per scene."""
    if spec.store == "auto":
        return len(spec.cameras) > break_even_cameras()
    return spec.store == "always"


def store_serves(spec: CaptureSpec) -> bool:
    """Whether a store can give this camera's capture (:mod:`pacam_render.lightfield.codes`):
    its camera does not move (not Levin's), it has a lens (not the pinhole reference), its
    diffraction is not asked in the rays, and an LCoS that switches (the spec's or its design
    file's) does so between discrete discs, which stores blend as the plugin draws them."""
    schedule = MODES[spec.mode].schedule
    if schedule is None or schedule not in SERVED or spec.diffraction == "on":
        return False
    plan = plan_capture(spec)  # the design file's own LCoS and schedule, as synthesis reads it
    params = plan.sensor_params()
    try:
        check_served(plan.aperture(params), params)
    except ParameterError:
        return False
    return True
