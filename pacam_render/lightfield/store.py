"""A light-field store on disk: the samples of one render through the whole lens.

A store is a folder: ``store.json`` (what was rendered, its steps and its digest), one
``.npz`` shard per pass and time step (each sample's film point, lens point, time and
radiance, :mod:`.trace`), and ``truth.npz`` (the capture's ground-truth layers, rendered once).
Every file is written under a temporary name and renamed, so a shard on disk is a finished one:
an interrupted store resumes by skipping them, and gives the same bits as an uninterrupted one.

Per-sample records rather than bins: a design's reweighting needs the lens point and the time
of each sample exactly (a bitmap's LCoS pixels are 13.6 um, an opening's edge is sharp, and a
refocused design moves each sample by its lens point), so any binning of (u, v, t) would put a
discretisation error on every design. Records cost 32 bytes a sample (RGB), which the budget
below counts before any work.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import ParameterError, check_positive
from ..exposure.spec import CaptureSpec
from ..io.outputs import atomic_save, write_json
from ..limits import available_bytes, gib
from .trace import CHUNK_LANES

FORMAT = "pacam-lightfield/1"
RECORD_FIELDS = ("x", "y", "u", "v", "p")
"""Per-sample float32 fields beside the radiance: film point (px), lens point (mm) and the
proposal's density there (1/mm^2)."""
DISK_BYTES = 20 * 2**30
"""The most disk a store may take unless ``max_disk_gib`` raises it (the issue's 20 GB)."""


@dataclass(frozen=True)
class StoreSpec:
    """What a store renders: a capture's window, its samples and the designs it must serve.

    ``capture`` (a :class:`~pacam_render.exposure.spec.CaptureSpec`) gives the scene,
    the sensor size, the window (``crop``), the design whose field of view and focus the store
    camera takes (``preset`` or ``design``, ``object_depth_mm``), ``spp`` per pass, ``passes``,
    ``seed``, ``max_step_px`` and ``grey``. ``margin_px`` widens the film on every side, so
    that designs focused elsewhere (a normal capture focuses on the object) find every ray that
    reaches their window (:mod:`.geometry`); None: what the proposal's designs need.
    ``focus_mm`` is the store camera's focus (None: the design's coded focus).
    """

    capture: CaptureSpec
    margin_px: int | None = None
    focus_mm: float | None = None
    designs: tuple = ()
    """CaptureSpecs of the designs the proposal focuses on (:mod:`.proposal`); empty: the
    capture's own design in its coded and normal modes."""
    alpha: float = 0.2
    """The proposal's uniform share (:data:`~.proposal.DEFENSIVE`)."""

    def __post_init__(self) -> None:
        m = self.margin_px
        if m is not None and (not isinstance(m, (int, np.integer)) or m < 0):
            raise ParameterError(f"margin_px must be an integer >= 0, got {self.margin_px!r}")
        if self.focus_mm is not None:
            check_positive("focus_mm", self.focus_mm, "mm")

    def to_json(self) -> dict:
        return {"capture": asdict(self.capture), "margin_px": self.margin_px,
                "focus_mm": self.focus_mm, "designs": [asdict(d) for d in self.designs],
                "alpha": self.alpha}  # fmt: skip

    def key(self) -> str:
        """A hash of everything that changes the samples (for resuming)."""
        h = hashlib.sha256(self.capture.key().encode())
        h.update(json.dumps([self.margin_px, self.focus_mm, self.alpha]).encode())
        for d in self.designs:
            h.update(d.key().encode())
        return h.hexdigest()[:16]


def shard_name(pass_index: int, step: int) -> str:
    return f"p{pass_index:02d}_s{step:04d}.npz"


def bytes_per_sample(channels: int, per_sample_time: bool) -> int:
    """A record's size on disk: four float32 fields, the time where it varies, the radiance."""
    return 4 * (len(RECORD_FIELDS) + int(per_sample_time) + channels)


LANE_BYTES = 370
"""Peak memory per ray of a wavefront: Dr.Jit's state and the host copies, measured (a static
400x160 window at 32 spp, 2 M rays: 720 MB)."""


def check_budget(samples: int, largest: int, per: int, out: Path, max_disk: int) -> None:
    """Refuse a store whose disk or one shard's memory would not fit, with the numbers:
    ``samples`` in all, ``largest`` in one shard, ``per`` bytes each on disk. A shard's rays
    are traced in wavefronts of at most :data:`~.trace.CHUNK_LANES`; its records are held
    about three times (the wavefronts' parts, their concatenation, the file)."""

    nbytes = samples * per
    if nbytes > max_disk:
        raise ParameterError(
            f"the store needs {gib(nbytes)} on disk ({samples:.4g} samples), above the limit of "
            f"{gib(max_disk)}; lower `spp`, `passes` or the window (`crop`), or raise max_disk"
        )
    peak = min(largest, CHUNK_LANES) * LANE_BYTES + 3 * largest * per
    if peak > available_bytes():
        raise ParameterError(
            f"one step of the store needs about {gib(peak)} of memory and "
            f"{gib(available_bytes())} is available; lower `spp` or the window (`crop`)"
        )
    probe = next(p for p in (out, *out.parents) if p.exists())  # the folder may not exist yet
    free = shutil.disk_usage(probe).free
    if nbytes > free:
        raise ParameterError(
            f"the store needs {gib(nbytes)} on disk and {gib(free)} is free at {probe}; lower "
            "`spp`, `passes` or the window (`crop`)"
        )


def shard_digest(records: dict, meta: dict) -> str:
    """The SHA-256 (16 hex digits) of a shard's arrays and meta: the store's digest's part."""
    h = hashlib.sha256()
    for k in sorted(records):
        h.update(k.encode() + np.ascontiguousarray(records[k]).tobytes())
    h.update(json.dumps(meta, sort_keys=True).encode())
    return h.hexdigest()[:16]


def save_shard(folder: Path, name: str, records: dict, meta: dict) -> str:
    """Write one shard atomically; return its :func:`shard_digest`."""

    def save(tmp: str) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **records, meta=np.frombuffer(json.dumps(meta).encode(), np.uint8))

    atomic_save(folder / name, save, force=True)
    return shard_digest(records, meta)


def load_shard(path: Path) -> tuple[dict, dict]:
    """A shard's records and its meta (the step's times and samples)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            return {k: z[k] for k in z.files if k != "meta"}, meta
    except (OSError, ValueError, KeyError) as exc:
        raise ParameterError(f"{path}: not a readable light-field shard ({exc})") from None


@dataclass(frozen=True)
class StoreCamera:
    """The store camera's geometry (``store.json``'s ``camera``): what a synthesis needs to
    place its samples.

    Attributes
    ----------
    window : (int, int, int, int)
        The capture window (x, y, w, h), px of the sensor.
    sensor_px : (int, int)
        The sensor's (W, H), px.
    margin_px : int
        The film's margin around the window on every side, px.
    focus_mm, lens_radius_mm, fov_deg : float
        The store camera's focus, its lens radius R_max (mm) and horizontal field (deg).
    f_px : float
        The focal length in px of the sensor (:func:`~pacam_render.model.optics.focal_length_px`).
    exposure_ms : float
        The store's shutter interval, ms.
    """

    window: tuple[int, int, int, int]
    sensor_px: tuple[int, int]
    margin_px: int
    focus_mm: float
    lens_radius_mm: float
    fov_deg: float
    f_px: float
    exposure_ms: float


class StoreStep(NamedTuple):
    """One time step of a store pass: its interval on the store's shutter clock (ms) and its
    samples per pixel."""

    t0_ms: float
    t1_ms: float
    spp: int


@dataclass(frozen=True)
class Manifest:
    """A finished store's ``store.json``, read and typed in one place (:meth:`from_json`).

    Attributes
    ----------
    key : str
        The hash of what changes the samples (:meth:`StoreSpec.key`).
    capture : dict
        The capture the store renders (``spec.capture``: a
        :class:`~pacam_render.exposure.spec.CaptureSpec`'s fields).
    camera : StoreCamera
        The store camera's geometry.
    scene, scene_digest : str
        The scene's name and the digest of its description and motion.
    channels, passes : int
        Radiance channels (1 grey, 3 RGB) and independent passes.
    steps : tuple of tuple of StoreStep
        Each pass's time steps.
    mid_ms : float
        The paper's t = 0 on the store's shutter clock, ms.
    seconds : float
        The tracing's seconds in all.
    digest : str
        The store's digest (:func:`store_digest`).
    raw : dict
        The JSON as read (the spec, proposal, noise target, versions).
    """

    key: str
    capture: dict
    camera: StoreCamera
    scene: str
    scene_digest: str
    channels: int
    passes: int
    steps: tuple
    mid_ms: float
    seconds: float
    digest: str
    raw: dict = field(repr=False)

    @property
    def samples_per_pass(self) -> int:
        """Samples per pixel of one pass (every pass has the same steps)."""
        return sum(s.spp for s in self.steps[0])

    @classmethod
    def from_json(cls, d: dict, where: str) -> Manifest:
        """The manifest of ``d`` (read from ``where``), or a one-line refusal naming it."""
        try:
            cam = d["camera"]
            camera = StoreCamera(
                tuple(int(v) for v in cam["window"]), tuple(int(v) for v in cam["sensor_px"]),
                int(cam["margin_px"]), float(cam["focus_mm"]), float(cam["lens_radius_mm"]),
                float(cam["fov_deg"]), float(cam["f_px"]), float(cam["exposure_ms"]),
            )  # fmt: skip
            steps = tuple(tuple(StoreStep(float(a), float(b), int(n)) for a, b, n in row)
                          for row in d["steps"])  # fmt: skip
            out = cls(
                str(d["key"]), dict(d["spec"]["capture"]), camera, str(d["scene"]),
                str(d.get("scene_digest")), int(d["channels"]), int(d["passes"]), steps,
                float(d["mid_ms"]), float(d.get("seconds", 0.0)), str(d["digest"]), d,
            )  # fmt: skip
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise ParameterError(f"{where}: not a readable store manifest ({exc!r})") from None
        if len(out.steps) != out.passes or not out.steps:
            raise ParameterError(f"{where}: {out.passes} passes but {len(out.steps)} step rows")
        return out


@dataclass
class Store:
    """A store read back: its folder and manifest (``store.json``). Shards read once are kept
    in memory up to ``cache_bytes`` (a quarter of the memory available when it opens), so
    that many designs synthesised from one store read the disk once."""

    folder: Path
    manifest: Manifest
    cache_bytes: int = 0
    _cache: dict = field(default_factory=dict, repr=False)
    _cached: int = 0

    @classmethod
    def open(cls, folder) -> Store:
        path = Path(folder) / "store.json"
        if not path.is_file():
            raise ParameterError(f"no light-field store at {folder} (its store.json is missing)")
        try:
            manifest = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise ParameterError(f"{path} is not valid JSON ({exc})") from None
        if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
            raise ParameterError(f"{path} is not a {FORMAT} store")
        if not manifest.get("complete"):
            raise ParameterError(
                f"the store at {folder} is not finished: run `pacam lightfield` again to resume"
            )
        manifest = Manifest.from_json(manifest, str(path))
        return cls(Path(folder), manifest, cache_bytes=available_bytes() // 4)

    @property
    def digest(self) -> str:
        return self.manifest.digest

    def shards(self, pass_index: int):
        """(records, meta) of each of a pass's shards, in step order, one at a time."""
        for step in range(len(self.manifest.steps[pass_index])):
            name = shard_name(pass_index, step)
            if name in self._cache:
                yield self._cache[name]
                continue
            shard = load_shard(self.folder / name)
            size = sum(a.nbytes for a in shard[0].values())
            if self._cached + size <= self.cache_bytes:
                self._cache[name] = shard
                self._cached += size
            yield shard

    def truth(self) -> tuple[dict, dict | None, float | None]:
        """The ground-truth layers, the ``object_id`` legend and the ``sharp`` layer's Monte
        Carlo sigma (white = 1; None for a store written before it was kept); empty without
        truth."""
        path = self.folder / "truth.npz"
        if not path.is_file():
            return {}, None, None
        records, meta = load_shard(path)
        return records, meta.get("objects"), meta.get("sharp_mc_sigma")


def write_manifest(folder: Path, manifest: dict) -> None:
    write_json(folder / "store.json", manifest, force=True)


def store_digest(key: str, shard_digests: list[list[str]]) -> str:
    h = hashlib.sha256(key.encode())
    for row in shard_digests:
        h.update(",".join(row).encode())
    return h.hexdigest()[:16]


def planned_samples(steps: list[list[tuple]], pixels: int) -> tuple[int, int]:
    """Total samples of a store's steps, and those of its largest shard."""
    per = [s[2] * pixels for row in steps for s in row]
    return sum(per), max(per)
