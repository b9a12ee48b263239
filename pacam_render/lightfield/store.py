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
import stat
import weakref
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import ParameterError, check_positive
from ..exposure.spec import CaptureSpec
from ..io.arrays import read_json
from ..io.outputs import atomic_save, write_json
from ..limits import available_bytes, free_disk, gib
from .trace import CHUNK_LANES

FORMAT = "pacam-lightfield/1"
TRUTH_POSE_MS = 0.0
"""The time (ms from mid-exposure) of the pose the truth layers show, written into
``truth.npz``'s meta. A moving scene's store whose truth lacks it had its truth layers
rendered at its last step's pose (the shards left the description's shared meshes there)."""
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


def scene_digest(desc) -> str:
    """The digest of what a store renders of a scene: its description and its motions (a store
    rendered before ``scene.motion.json`` changed is another scene's)."""
    return f"{desc.digest()}-{desc.motion_digest()}"


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
    probe, free = free_disk(out)  # the folder may not exist yet
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


MAX_SHARD_BYTES = 64 * 2**30
"""The largest shard file read (a store's whole disk budget is :data:`DISK_BYTES`)."""


def load_shard(path: Path) -> tuple[dict, dict]:
    """A shard's records and its meta (the step's times and samples), or a one-line refusal
    naming the file: a missing, empty, truncated or linked-away file, or one that is not an
    ``.npz`` of arrays, whatever numpy raises on it."""
    path = Path(path)
    try:
        info = path.stat()
    except OSError as exc:
        raise ParameterError(f"{path}: the store's file cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):  # a FIFO would hang the read, a device never ends
        raise ParameterError(f"{path}: not a regular file (a store's shards are .npz files)")
    if info.st_size > MAX_SHARD_BYTES:
        raise ParameterError(f"{path}: {gib(info.st_size)}, larger than any shard a store writes")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            records = {k: z[k] for k in z.files if k != "meta"}
    except Exception as exc:  # noqa: BLE001 - BadZipFile, EOFError, KeyError, ...: one line
        raise ParameterError(
            f"{path}: not a readable light-field shard ({_why(exc)}); the store is damaged: "
            "render it again"
        ) from None
    if not isinstance(meta, dict):
        raise ParameterError(f"{path}: its meta is not an object; the store is damaged")
    return records, meta


def _why(exc: Exception) -> str:
    """What went wrong reading a file, in a few words (never numpy's advice to unpickle)."""
    text = str(exc)
    if "pickle" in text or not text:
        text = "not an .npz archive of arrays"
    return f"{type(exc).__name__}: {text[:200]}"


def check_shard(records: dict, meta: dict, channels: int, exposure_ms: float, path) -> None:
    """Refuse a shard whose arrays or meta no store writes, naming the file: the record fields
    (:data:`RECORD_FIELDS`, float32, one value per sample), the radiance ``L`` (channels, n),
    finite and non-negative, a time ``t`` where it varies, and a step inside the exposure
    with spp > 0."""
    missing = [k for k in (*RECORD_FIELDS, "L") if k not in records]
    if missing:
        raise ParameterError(f"{path}: the shard lacks {', '.join(missing)}; the store is damaged")
    n = records["x"].shape[0] if records["x"].ndim == 1 else -1
    for k in (*RECORD_FIELDS, *(("t",) if "t" in records else ())):
        a = records[k]
        if a.dtype != np.float32 or a.shape != (n,):
            raise ParameterError(
                f"{path}: its {k} is {a.dtype} of shape {a.shape}, not float32 of shape ({n},)"
            )
    L = records["L"]
    if L.dtype != np.float32 or L.shape != (channels, n):
        raise ParameterError(
            f"{path}: its radiance L is {L.dtype} of shape {L.shape}, not float32 of shape "
            f"({channels}, {n}) (the store's channels)"
        )
    if not np.isfinite(L).all() or (L < 0).any():
        raise ParameterError(
            f"{path}: its radiance holds values that are not finite or are negative (least "
            f"{np.nanmin(L):.3g}); a render gives none: the store is damaged or edited"
        )
    try:
        t0, t1, spp = float(meta["t0"]), float(meta["t1"]), meta["spp"]
    except (KeyError, TypeError, ValueError):
        raise ParameterError(
            f"{path}: its meta lacks t0, t1 or spp; the store is damaged"
        ) from None
    if not (isinstance(spp, int) and spp > 0 and 0.0 <= t0 < t1 <= exposure_ms * (1 + 1e-9)):
        raise ParameterError(
            f"{path}: its step ({t0:g} to {t1:g} ms, spp {spp!r}) is not a step of the store's "
            f"{exposure_ms:g} ms exposure with spp > 0"
        )


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
    shard_digests : tuple of tuple of str
        Each shard's :func:`shard_digest`, pass by pass: checked when the shard is read.
    truth_digest : str or None
        ``truth.npz``'s digest (None: the store has no truth layers).
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
    shard_digests: tuple
    truth_digest: str | None
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
            shards = tuple(tuple(str(x) for x in row) for row in d["shard_digests"])
            truth = d.get("truth_digest")
            out = cls(
                str(d["key"]), dict(d["spec"]["capture"]), camera, str(d["scene"]),
                str(d.get("scene_digest")), int(d["channels"]), int(d["passes"]), steps,
                float(d["mid_ms"]), float(d.get("seconds", 0.0)), str(d["digest"]), shards,
                None if truth is None else str(truth), d,
            )  # fmt: skip
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise ParameterError(
                f"{where}: not a readable store manifest (missing or malformed {exc!s}); "
                "render the store again"
            ) from None
        out.check(where)
        return out

    def check(self, where: str) -> None:
        """Refuse a manifest that no store writes (a hand edit), naming the file and the field:
        its own digest (:func:`manifest_digest`), then each value against the rest."""
        recorded = self.raw.get("manifest_digest")
        if recorded is None:
            raise ParameterError(
                f"{where}: the store was written by an earlier pacam, without the digest of its "
                "manifest, and cannot be verified: render it again"
            )
        if manifest_digest(self.raw) != recorded:
            raise ParameterError(
                f"{where}: the manifest was edited (its digest is not the one recorded when the "
                "store was written): render the store again rather than edit it"
            )
        cam, spec = self.camera, self.capture
        positive = {"exposure_ms": cam.exposure_ms, "f_px": cam.f_px, "fov_deg": cam.fov_deg,
                    "lens_radius_mm": cam.lens_radius_mm, "focus_mm": cam.focus_mm}  # fmt: skip
        for name, v in positive.items():
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"{where}: camera.{name} must be > 0, got {v!r}")
        crop = spec.get("crop") or (0, 0, spec.get("width"), spec.get("height"))
        if list(cam.window) != list(crop) or cam.window[2] <= 0 or cam.window[3] <= 0:
            raise ParameterError(f"{where}: camera.window {list(cam.window)} is not the "
                                 f"capture's window {list(crop)}")  # fmt: skip
        if self.channels != (1 if spec.get("grey") else 3) or self.passes < 1:
            raise ParameterError(f"{where}: {self.channels} channels and {self.passes} passes do "
                                 "not fit the capture")  # fmt: skip
        rows = [len(r) for r in self.steps]
        if len(rows) != self.passes or rows != [len(r) for r in self.shard_digests] or not rows[0]:
            raise ParameterError(f"{where}: its steps and shard digests do not fit its "
                                 f"{self.passes} passes")  # fmt: skip
        for s in self.steps[0]:
            if not (s.spp > 0 and 0.0 <= s.t0_ms < s.t1_ms <= cam.exposure_ms * (1 + 1e-9)):
                raise ParameterError(f"{where}: step {tuple(s)} is not inside the exposure")
        if store_digest(self.key, [list(r) for r in self.shard_digests]) != self.digest:
            raise ParameterError(f"{where}: its digest is not its shards' digest")


MANIFEST_UNHASHED = ("manifest_digest", "seconds", "versions")
"""Manifest keys its own digest leaves out: the digest itself, and what does not change a
capture (the tracing's seconds, the versions that wrote it)."""


def manifest_digest(manifest: dict) -> str:
    """The SHA-256 (16 hex digits) of a manifest's content but :data:`MANIFEST_UNHASHED`: written
    when the store is finished, checked when it is read."""
    kept = {k: v for k, v in manifest.items() if k not in MANIFEST_UNHASHED}
    return hashlib.sha256(json.dumps(kept, sort_keys=True).encode()).hexdigest()[:16]


_SHARED_CACHE = {"budget": None, "used": 0}
"""The shard caches of every open store together: at most a quarter of the memory available
when the first store opened (a search over eight stores once pinned eight quarters' worth,
22 of 23 GiB), released as stores are dropped."""


def _release(account: list) -> None:
    _SHARED_CACHE["used"] -= account[0]


@dataclass
class Store:
    """A store read back: its folder and manifest (``store.json``). Shards read once are kept
    in memory up to ``cache_bytes`` (a quarter of the memory available when it opens), and all
    open stores' caches together up to a quarter of the memory available when the first one
    opened, so that many designs synthesised from one store read the disk once."""

    folder: Path
    manifest: Manifest
    cache_bytes: int = 0
    _cache: dict = field(default_factory=dict, repr=False)
    _cached: int = 0
    _account: list = field(default_factory=lambda: [0], repr=False)

    def __post_init__(self) -> None:
        if _SHARED_CACHE["budget"] is None:
            _SHARED_CACHE["budget"] = available_bytes() // 4
        weakref.finalize(self, _release, self._account)

    @classmethod
    def open(cls, folder) -> Store:
        path = Path(folder) / "store.json"
        if not path.is_file():
            raise ParameterError(f"no light-field store at {folder} (its store.json is missing)")
        manifest = read_json(path, "the store's manifest")
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
        """(records, meta) of each of a pass's shards, in step order, one at a time, each
        verified against the manifest (:meth:`read_shard`)."""
        for step in range(len(self.manifest.steps[pass_index])):
            name = shard_name(pass_index, step)
            if name in self._cache:
                yield self._cache[name]
                continue
            shard = self.read_shard(pass_index, step)
            size = sum(a.nbytes for a in shard[0].values())
            shared = _SHARED_CACHE["used"] + size <= _SHARED_CACHE["budget"]
            if self._cached + size <= self.cache_bytes and shared:
                self._cache[name] = shard
                self._cached += size
                self._account[0] += size
                _SHARED_CACHE["used"] += size
            yield shard

    def read_shard(self, pass_index: int, step: int) -> tuple[dict, dict]:
        """One shard, refused in one line naming its file unless it is the one the manifest
        recorded (its digest: not another window's, pass's or store's) and holds what a render
        writes (:func:`check_shard`: finite, non-negative radiance)."""
        path = self.folder / shard_name(pass_index, step)
        records, meta = load_shard(path)
        got, want = shard_digest(records, meta), self.manifest.shard_digests[pass_index][step]
        if got != want:
            raise ParameterError(
                f"{path}: its digest {got} is not the {want} that store.json recorded: the shard "
                "was replaced or changed (another window's, another pass's or another store's); "
                "render the store again"
            )
        m = self.manifest
        check_shard(records, meta, m.channels, m.camera.exposure_ms, path)
        return records, meta

    def truth(self, moving: bool = True) -> tuple[dict, dict | None, float | None]:
        """The ground-truth layers, the ``object_id`` legend and the ``sharp`` layer's Monte
        Carlo sigma (white = 1); empty for a store rendered without truth. The file is the
        one the manifest recorded, or refused naming it; a ``moving`` scene's layers must
        show its t = 0 pose (:data:`TRUTH_POSE_MS`), or they are refused with the way to
        render them again (the samples are kept)."""
        want = self.manifest.truth_digest
        if want is None:
            return {}, None, None
        path = self.folder / "truth.npz"
        records, meta = load_shard(path)
        if shard_digest(records, meta) != want:
            raise ParameterError(f"{path}: not the truth layers store.json recorded (its digest "
                                 "differs); render the store again")  # fmt: skip
        if moving and meta.get("pose_ms") != TRUTH_POSE_MS:
            raise ParameterError(
                f"{path}: this moving scene's truth layers do not record their pose: stores "
                "written before it was recorded show the last step's pose, not t = 0 (a bug), "
                "and scores against them are wrong. Run the command that rendered the store "
                "again (pacam lightfield, or the dataset's): it renders the truth layers again "
                "and keeps the samples"
            )
        return records, meta.get("objects"), meta.get("sharp_mc_sigma")


def write_manifest(folder: Path, manifest: dict) -> None:
    write_json(folder / "store.json", manifest, force=True)


def store_digest(key: str, shard_digests: list[list[str]]) -> str:
    h = hashlib.sha256(key.encode())
    for row in shard_digests:
        h.update(",".join(row).encode())
    return h.hexdigest()[:16]


def planned_samples(steps: list[tuple], passes: int, pixels: int) -> tuple[int, int]:
    """Total samples of a store whose ``passes`` passes each take ``steps`` ((t0, t1, spp)
    each) over ``pixels``, and those of its largest shard: by arithmetic, since a list of the
    passes' steps is itself too large for an absurd ``passes``."""
    per = [s[2] * pixels for s in steps]
    return int(passes) * sum(per), max(per)
