"""One render of a dataset, on a worker: the capture, then per light level a sample folder.

A sample's folder ``samples/<id>/`` holds the capture as ``pacam render`` writes it
(capture.exr with the layers ``capture``, ``sharp``, ``depth``, ``object_id``, ``velocity``,
``relative_illumination`` and the sensor's ``raw`` (DN) and ``noisy`` (the capture's units);
capture.png; capture.json), the capture's own analytic PSF as ``pacam psf --like`` writes it
(psf_analytic.exr, psf_analytic.png, psf.json; registered to the pinhole image) and
sample.json (its id, key and digest). It is written to a temporary folder beside it and
renamed into place, so a sample folder is whole or absent.
"""

from __future__ import annotations

import copy
import hashlib
import json
import shutil
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..capture.kernels import analytic_psf, capture_diffraction
from ..errors import ParameterError
from ..exposure.direct import render_capture, write_capture
from ..exposure.estimate import AbsoluteTarget
from ..exposure.integrate import CaptureInterrupted
from ..io.exr import write_exr
from ..io.outputs import write_json
from ..io.preview import write_psf_preview
from ..lightfield import StoreSpec, render_lightfield, synthesize
from ..limits import DEFAULT_MAX_SAMPLES, DEFAULT_MAX_STEPS, PacamWarning
from ..model.camera import CameraDesign
from ..model.modes import MODES_WITH_PSF
from ..psf.origin import origin_record
from ..scenes import load_scene
from ..sensor.apply import SensorTarget, add_sensor_layers
from ..sensor.model import SensorModel
from .index import row
from .plan import Render

SAMPLES = "samples"
SAMPLE_JSON = "sample.json"


@dataclass(frozen=True)
class RenderTask:
    """What a worker needs for one render (picklable): the render (or a scene's renders from
    one light-field store), the samples still to write, the dataset's folder, the sensor, the
    noise target and the bounds."""

    renders: tuple[Render, ...]
    todo: tuple[str, ...]
    out: str
    sensor: str
    target: dict | None = None
    psf_velocity_px_per_ms: float = 0.0
    scene_file: str | None = None
    """A family seed's generated scene.xml (None: ``render.scene`` loads as it is)."""
    max_samples: int = DEFAULT_MAX_SAMPLES
    max_steps: int = DEFAULT_MAX_STEPS

    @property
    def render(self) -> Render:
        """The first render (the only one of a direct task)."""
        return self.renders[0]

    @property
    def store(self) -> bool:
        """Whether the renders are synthesised from one store of their scene."""
        return self.renders[0].via == "store"

    def samples(self, render: Render | None = None) -> list:
        """The samples still to write (of ``render`` only, if given)."""
        rs = self.renders if render is None else (render,)
        return [s for r in rs for s in r.samples if s.id in self.todo]


def make_target(target: dict | None, sensor: str):
    """The render's noise target from the plan's description of it (None: ``spp``)."""
    if target is None:
        return None
    if "sigma" in target:
        return AbsoluteTarget(target["sigma"])
    return SensorTarget(target["ratio"], tuple((sensor, lv) for lv in target["levels"]))


def render_task(task: RenderTask) -> list[dict]:
    """Render ``task`` and write its samples; index rows for them, ``failed`` with the error
    when anything but an interrupt goes wrong (the next run retries them). The captures' notes
    are not shown (a dataset would repeat them per render): each capture.json keeps its own
    under ``notes``."""
    todo = task.samples()
    try:
        with warnings.catch_warnings():  # each capture keeps its notes in capture.json
            warnings.simplefilter("ignore", PacamWarning)
            if task.store:
                return _store_and_write(task)
            return _render_and_write(task, todo)
    except (CaptureInterrupted, KeyboardInterrupt):
        raise
    except Exception as exc:  # noqa: BLE001 - recorded in the index, retried next run
        return [row(s, "failed", f"{type(exc).__name__}: {exc}") for s in todo]


def _render_and_write(task: RenderTask, todo: list) -> list[dict]:
    t0 = time.perf_counter()
    desc = load_scene(task.scene_file) if task.scene_file else None
    cap = _direct(task, task.render, desc)
    return _write_samples(task, cap, todo, time.perf_counter() - t0)


def _direct(task: RenderTask, r: Render, desc):
    """``r``'s capture rendered directly (checkpointed under ``.renders/``)."""
    partial = Path(task.out) / ".renders" / r.samples[0].key / "partial"
    cap = render_capture(
        r.spec, partial_dir=partial, progress=False, description=desc, truth=True,
        max_steps=task.max_steps, max_samples=task.max_samples,
        target=make_target(task.target, task.sensor),
    )  # fmt: skip
    shutil.rmtree(partial.parent, ignore_errors=True)
    return cap


def _store_and_write(task: RenderTask) -> list[dict]:
    """One light-field store of the scene (proposal: the task's cameras), each camera's
    capture synthesised from it (:func:`~pacam_render.lightfield.synthesis.synthesize`; a
    camera it cannot serve after all renders directly, and its record says why), then the
    samples. The store is removed once its samples are written."""
    t0 = time.perf_counter()
    desc = load_scene(task.scene_file or task.render.scene)
    folder = Path(task.out) / ".stores" / task.render.samples[0].key
    spec = StoreSpec(capture=task.render.spec, designs=tuple(r.spec for r in task.renders))
    store = render_lightfield(
        spec, folder, progress=False, max_steps=task.max_steps, description=desc,
        target=make_target(task.target, task.sensor),
    )  # fmt: skip
    share = (time.perf_counter() - t0) / len(task.renders)
    rows = []
    for r in task.renders:
        t1 = time.perf_counter()
        try:
            cap = synthesize(store, r.spec, progress=False, description=desc)
        except ParameterError as exc:  # e.g. a refocus beyond the store's margin
            cap = _direct(task, r, desc)
            cap.record.notes.append(
                f"rendered directly: the light-field store cannot serve it ({exc})"
            )
        rows += _write_samples(task, cap, task.samples(r), share + time.perf_counter() - t1)
    shutil.rmtree(folder, ignore_errors=True)
    return rows


def _write_samples(task: RenderTask, cap, todo: list, seconds: float) -> list[dict]:
    """Each of ``todo``'s samples: the capture through the sensor at its light level."""
    model = SensorModel.from_preset(task.sensor)
    rows = []
    for s in todo:
        one = copy.deepcopy(cap)
        add_sensor_layers(one, model, task.sensor, s.light_level, s.sensor_seed)
        digest = write_sample(one, Path(task.out), s, task.psf_velocity_px_per_ms, seconds)
        err = one.record.render_error
        rows.append(row(s, "ok", render_error=err.mc_sigma, ratio_to_sensor=err.ratio_to_sensor,
                        seconds=seconds, digest=digest))  # fmt: skip
    return rows


def write_sample(cap, out: Path, sample, velocity: float, seconds: float) -> str:
    """Write ``sample``'s folder (module docstring) from its capture, through a temporary
    folder renamed into place (an older folder of the same id is replaced); its digest."""
    root = out / SAMPLES
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{sample.id}.", dir=root))
    try:
        write_capture(cap, tmp)
        kernel = write_psf(cap, tmp, velocity)
        digest = sample_digest(cap, kernel)
        meta = {"id": sample.id, "key": sample.key, "digest": digest, "scene": sample.scene,
                "camera": sample.camera, "light_level": sample.light_level,
                "sensor_seed": sample.sensor_seed, "render_seconds": seconds,
                "render_error": cap.record.render_error.mc_sigma,
                "ratio_to_sensor": cap.record.render_error.ratio_to_sensor}  # fmt: skip
        write_json(tmp / SAMPLE_JSON, meta)
        final = root / sample.id
        if final.exists():
            shutil.rmtree(final)
        tmp.rename(final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return digest


def write_psf(cap, folder: Path, velocity: float) -> np.ndarray | None:
    """The capture's analytic PSF at ``velocity`` px/ms (pinhole registration, the capture's
    diffraction and LCoS leak: :func:`~pacam_render.capture.kernels.analytic_psf`), as
    ``pacam psf --like`` writes it; None (nothing written) for a mode without one."""
    rec = cap.record
    if rec.mode not in MODES_WITH_PSF:
        return None
    k = analytic_psf(rec, velocity)
    cam = CameraDesign.from_inputs(rec.camera)
    write_exr(folder / "psf_analytic.exr", {"psf": k})
    write_psf_preview(folder / "psf_analytic.png", k, f"analytic PSF, {rec.mode}, s = {velocity:g}"
                      " px/ms")  # fmt: skip
    meta = {
        **cam.summary(), "mode": rec.mode, "camera": cam.inputs(),
        "velocity_px_per_ms": velocity, "size_px": list(k.shape),
        "diffraction": capture_diffraction(rec), **({"crop": rec.crop} if rec.crop else {}),
        **origin_record(cam, rec.mode, "pinhole"),
        "psf_origin": "centre pixel = where a pinhole at the lens centre images the point at t = 0",
    }  # fmt: skip
    write_json(folder / "psf.json", meta)
    return k


def sample_digest(cap, kernel: np.ndarray | None) -> str:
    """A digest of a sample's arrays as written (float32): every layer, and the PSF."""
    return layers_digest({"capture": cap.image, **cap.extra_layers}, kernel)


def layers_digest(layers: dict, kernel: np.ndarray | None) -> str:
    """:func:`sample_digest` of layers by name (as capture.exr holds them) and the PSF."""
    h = hashlib.sha256()
    layers = dict(layers)
    if kernel is not None:
        layers["psf"] = kernel
    for name in sorted(layers):
        h.update(name.encode())
        h.update(np.ascontiguousarray(layers[name], dtype=np.float32).tobytes())
    return h.hexdigest()[:16]


def finished(out: Path, sample) -> dict | None:
    """The index row of ``sample`` when its folder is finished with its key (sample.json),
    else None: a folder of another key, or none, is rendered (again)."""
    path = Path(out) / SAMPLES / sample.id / SAMPLE_JSON
    try:
        meta = json.loads(path.read_text())
        if meta["key"] != sample.key:
            return None
        values = {k: meta[k] for k in ("digest", "render_error", "ratio_to_sensor")}
        return row(sample, "ok", seconds=meta["render_seconds"], **values)
    except (OSError, ValueError, KeyError, TypeError):
        return None
