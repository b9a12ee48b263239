"""LCoS aperture bitmaps as the camera design describes them: load, check and rasterise.

A *mask* is one greyscale image of the programmable aperture's LCoS display (the prototype's is
1280x1024 pixels at a 13.62 um pitch); its grey level is the transmittance, 0 (black, closed)
to 1 (white, open). A *mask stack* has shape ``(N, H, W)``: pattern ``k`` is shown during the
k-th of N equal shares of the exposure (see :mod:`pacam_render.model.schedule`).

Orientation (the one convention every function here, the analytic kernels and the camera plugin
share): a mask is the display as seen from the sensor looking into the scene, in the same
orientation as the rendered image. Column ``j`` grows to the image's right, row ``i`` grows
downwards, and the display centre is on the optical axis. In the camera's local frame (Mitsuba:
+z forward, +y up, +x to the image's *left*), pixel (i, j) of an ``H x W`` mask has its centre at

    x_mm = -(j + 0.5 - W/2) * pitch,        y_mm = (H/2 - i - 0.5) * pitch.

So a disc at aperture coordinate ``(c, 0)`` with c > 0 appears in the left half of the mask.
In the design's frame (x to the image's right, y downwards, as ``pattern_centres_mm``), the same
pixel is at ((j + 0.5 - W/2) pitch, (i + 0.5 - H/2) pitch).

Numpy only (Mitsuba is imported only to read an image file): :mod:`pacam_render.render.masks`
samples these stacks for the plugin.
"""

from __future__ import annotations

import base64
import hashlib
import os
import zipfile
import zlib
from collections.abc import Sequence

import numpy as np

from ..errors import ParameterError, check_positive
from ..io.arrays import read_npy
from ..io.image_header import check_image_size
from ..model.optics import LCOS_PITCH_MM
from .schedule import MAX_PATTERNS

DISPLAY_SHAPE = (1024, 1280)
"""Rows, columns of the prototype's LCoS display (SXGA, 1280x1024)."""
MAX_MASK_SIDE_PX = 8192
"""The widest or tallest mask image read: twice the widest LCoS displays (about 4096 px, 4K
and 10-megapixel SLMs), 6.4 times the prototype's. A mask image is measured from its header
before it is decoded (a 3.5 MB PNG declaring 60000 x 60000 px took 40 s and 3.35 GiB)."""


def pixel_centres_mm(shape: tuple[int, int], pitch_mm: float = LCOS_PITCH_MM):
    """Aperture-plane coordinates (mm) of the pixel centres: x per column, y per row."""
    h, w = (int(s) for s in shape)
    pitch = check_positive("mask_pitch", pitch_mm, "mm")
    x = -(np.arange(w) + 0.5 - w / 2.0) * pitch
    y = (h / 2.0 - np.arange(h) - 0.5) * pitch
    return x, y


def disc_mask(
    centre_mm: Sequence[float] = (0.0, 0.0),
    radius_mm: float = 1.0,
    shape: tuple[int, int] = DISPLAY_SHAPE,
    pitch_mm: float = LCOS_PITCH_MM,
    supersample: int = 1,
) -> np.ndarray:
    """A disc of transmittance 1 on the display, float32 ``(H, W)``.

    ``supersample = 1`` opens the pixels whose centre lies inside the disc (a binary mask, what
    an LCoS shows); ``supersample = s > 1`` gives each pixel the fraction of its s x s
    sub-pixel centres inside the disc (an anti-aliased grey mask, closer to the ideal disc).
    """
    r = check_positive("radius_mm", radius_mm, "mm")
    s = int(supersample)
    if s < 1:
        raise ParameterError(f"supersample must be an integer >= 1, got {supersample!r}")
    cx, cy = (float(v) for v in centre_mm)
    h, w = (int(v) for v in shape)
    pitch = check_positive("mask_pitch", pitch_mm, "mm")
    out = np.zeros((h, w), np.float32)
    x, y = pixel_centres_mm((h, w), pitch)
    # only the pixels whose square can touch the disc
    cols = np.flatnonzero(np.abs(x - cx) <= r + pitch)
    rows = np.flatnonzero(np.abs(y - cy) <= r + pitch)
    if cols.size == 0 or rows.size == 0:
        return out
    off = ((np.arange(s) + 0.5) / s - 0.5) * pitch  # sub-pixel offsets, centred in the pixel
    xs = (x[cols, None] - off[None, :]).reshape(-1)  # x falls with the column
    ys = (y[rows, None] - off[None, :]).reshape(-1)
    inside = ((xs[None, :] - cx) ** 2 + (ys[:, None] - cy) ** 2) <= r * r
    cover = inside.reshape(rows.size, s, cols.size, s).mean(axis=(1, 3))
    out[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1] = cover
    return out


def disc_masks(
    centres_mm,
    radius_mm: float,
    shape: tuple[int, int] = DISPLAY_SHAPE,
    pitch_mm: float = LCOS_PITCH_MM,
    supersample: int = 1,
) -> np.ndarray:
    """One :func:`disc_mask` per centre: a ``(N, H, W)`` stack (e.g. a parabolic schedule).

    ``centres_mm`` is ``(N,)`` (x only, y = 0) or ``(N, 2)``.
    """
    c = np.asarray(centres_mm, dtype=float)
    if c.ndim == 1:
        c = np.stack([c, np.zeros_like(c)], axis=1)
    return np.stack([disc_mask(ci, radius_mm, shape, pitch_mm, supersample) for ci in c])


def square_masks(
    centres_xy_mm,
    half_side_mm: float,
    shape: tuple[int, int] = DISPLAY_SHAPE,
    pitch_mm: float = LCOS_PITCH_MM,
) -> np.ndarray:
    """Binary square openings, one pattern per centre, ``(N, H, W)`` float32.

    Unlike :func:`disc_masks`, the centres are in the design's frame (x to the image's right,
    y downwards, mm: as ``CameraDesign.pattern_centres_mm``); a pixel is open when its centre
    lies within ``half_side_mm`` of the centre along both axes. A square of the area of a disc
    of radius R has ``half_side_mm = sqrt(pi) R / 2``.
    """
    half = check_positive("half_side_mm", half_side_mm, "mm")
    x, y = pixel_centres_mm(shape, pitch_mm)  # the plugin's local frame: -x, -y of the design's
    c = np.asarray(centres_xy_mm, dtype=float).reshape(-1, 2)
    return np.stack(
        [(np.abs(-x[None, :] - cx) <= half) & (np.abs(-y[:, None] - cy) <= half) for cx, cy in c]
    ).astype(np.float32)


def _as_array(source) -> np.ndarray:
    """ndarray from an array-like, a Dr.Jit tensor/array or a Mitsuba Bitmap."""
    if isinstance(source, np.ndarray):
        return source
    cls = type(source).__name__
    if cls == "Bitmap":
        arr = np.array(source)
        codes = arr.dtype in (np.uint8, np.uint16)  # levels: read as level / max, no gamma
        top = np.iinfo(arr.dtype).max if codes else 1.0
        if arr.ndim == 3:
            if arr.shape[2] in (2, 4):  # drop alpha
                arr = arr[..., :-1]
            if arr.shape[2] == 3:  # Rec. 709 luminance of the code values
                arr = arr @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float64)
            else:
                arr = arr[..., 0]
        if codes and arr.dtype.kind == "f":  # a colour image's luminance of its code values
            arr = np.clip(arr / top, 0.0, 1.0)
        return arr
    return np.array(source)


def code_levels(codes: np.ndarray) -> np.ndarray:
    """Transmittance of 8- or 16-bit code values: level / max, in float32 (correctly rounded,
    so equal to the float64 quotient rounded, for every level; 2x faster than a table)."""
    out = codes.astype(np.float32)
    np.divide(out, np.float32(np.iinfo(codes.dtype).max), out=out)
    return out


def _normalise(arr: np.ndarray, name: str) -> np.ndarray:
    """Transmittance in [0, 1] as float32; 8/16-bit integers are code values."""
    if arr.size == 0:
        raise ParameterError(f"{name}: empty mask (shape {arr.shape})")
    if arr.dtype == np.bool_:
        return arr.astype(np.float32)
    if arr.dtype in (np.uint8, np.uint16):  # image code values
        return code_levels(arr)
    if arr.dtype.kind == "c":
        raise ParameterError(f"{name}: transmittance must be real, got a complex array")
    if arr.dtype.kind not in "fiu" or arr.dtype.itemsize > 8:
        arr = arr.astype(np.float64)  # the rest (int64, float128, ...) checked in float64
    lo, hi = float(arr.min()), float(arr.max())  # NaN propagates; inf fails the range
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ParameterError(f"{name}: transmittance must be finite (found NaN or inf)")
    if lo < 0.0 or hi > 1.0:
        raise ParameterError(f"{name}: transmittance must be in [0, 1], got [{lo:g}, {hi:g}]")
    return arr.astype(np.float32, copy=arr.dtype != np.float32)


def _load_file(path: str, name: str = "mask_file") -> np.ndarray:
    if not os.path.isfile(path):
        raise ParameterError(f"{name}: no such file {path!r}")
    if path.lower().endswith(".npy"):
        return read_npy(path, name)
    if path.lower().endswith(".npz"):  # a design file's compressed stack (key ``masks``)
        try:
            with np.load(path, allow_pickle=False) as z:
                if "masks" not in z.files:
                    raise ParameterError(f"{name}: {path!r} holds no 'masks' array ({z.files})")
                return z["masks"]
        except (ValueError, EOFError, OSError, zipfile.BadZipFile) as exc:
            raise ParameterError(f"{name}: {path!r} is not a readable .npz ({exc})") from None
    import mitsuba as mi

    try:
        return _as_array(mi.Bitmap(path))
    except RuntimeError as exc:  # Mitsuba's "Unknown file format", a truncated stream
        why = str(exc).strip().splitlines()[-1][:200]
        raise ParameterError(
            f"{name}: {path!r} is not an image Mitsuba can read ({why}); masks are PNG, "
            "EXR or other image files, or a .npy stack"
        ) from None


def _check_image_header(path: str, name: str) -> None:
    """Refuse an image over :data:`MAX_MASK_SIDE_PX` a side from its header alone."""
    if os.path.isfile(path) and not path.lower().endswith((".npy", ".npz")):
        whose = "an LCoS mask may have (the widest LCoS displays have about 4096)"
        check_image_size(path, MAX_MASK_SIDE_PX, name, whose)


def load_masks(source, name: str = "masks") -> np.ndarray:
    """A float32 ``(N, H, W)`` transmittance stack from any supported source.

    ``source`` may be an array-like ``(H, W)`` or ``(N, H, W)`` (transmittance in [0, 1]; 8- and
    16-bit arrays and images are grey levels, read as level / 255 or level / 65535 with no gamma
    decoding), a Dr.Jit tensor, a Mitsuba ``Bitmap``, a sequence of any of these, a
    path to a ``.npy`` stack or an image, or a comma-separated string of such paths.
    """
    if isinstance(source, str):
        paths = [p.strip() for p in source.split(",") if p.strip()]
        if not paths:
            raise ParameterError(f"{name}: empty file list")
        file_name = "mask_file" if name == "masks" else name  # the plugin's parameter
        for p in paths:  # every header first: no mask decodes before a bomb among them is seen
            _check_image_header(p, file_name)
        parts = [_load_file(p, file_name) for p in paths]
    elif isinstance(source, (list, tuple)):
        if len(source) == 0:
            raise ParameterError(f"{name}: empty list of masks")
        parts = [_as_array(s) for s in source]
    else:
        parts = [_as_array(source)]
    stack = []
    for p in parts:
        a = _normalise(np.asarray(p), name)
        if a.ndim == 2:
            a = a[None]
        if a.ndim != 3:
            raise ParameterError(f"{name}: expected (H, W) or (N, H, W) masks, got shape {a.shape}")
        stack.append(a)
    shapes = {a.shape[1:] for a in stack}
    if len(shapes) != 1:
        raise ParameterError(f"{name}: all masks must have the same size, got {sorted(shapes)}")
    out = np.concatenate(stack, axis=0)
    if out.size == 0:
        raise ParameterError(f"{name}: empty mask (shape {out.shape})")
    return out


def check_masks(
    masks: np.ndarray, lens_radius_mm: float, pitch_mm: float = LCOS_PITCH_MM, reach2=None
):
    """Raise unless some pattern transmits light and no open pixel lies outside the lens.

    A pixel is outside the lens when its centre is farther than ``lens_radius_mm`` from the
    optical axis. Individual all-black patterns are allowed (the aperture is closed then, like
    a shutter); a stack that is black everywhere is not. ``reach2``: the stack's
    :func:`open_reach2_mm2`, when known.
    """
    R_max = check_positive("lens_radius", lens_radius_mm, "mm")
    if masks.ndim != 3 or masks.size == 0:
        raise ParameterError(f"masks: expected a non-empty (N, H, W) stack, got {masks.shape}")
    _check_reach(open_reach2_mm2(masks, pitch_mm) if reach2 is None else reach2, R_max, pitch_mm)


def open_reach2_mm2(masks: np.ndarray, pitch_mm: float) -> np.ndarray:
    """Each pattern's largest squared distance (mm^2) of an open pixel's centre from the
    optical axis; -1 for an all-black pattern."""
    x, y = pixel_centres_mm(masks.shape[1:], pitch_mm)
    r2 = x[None, :] ** 2 + y[:, None] ** 2
    return np.array([r2[m > 0].max(initial=-1.0) for m in masks])


def _check_reach(reach2: np.ndarray, R_max: float, pitch_mm: float) -> None:
    if not np.any(reach2 >= 0):
        raise ParameterError("masks: all patterns are black (transmittance 0 everywhere)")
    bad = np.flatnonzero(reach2 > R_max * R_max * (1 + 1e-9))
    if bad.size:
        r_px = R_max / pitch_mm
        raise ParameterError(
            f"masks: pattern(s) {bad.tolist()} open pixels outside the lens (lens_radius = "
            f"{R_max:g} mm = {r_px:.1f} display px from the display centre); opening must be "
            f"inside the lens"
        )


def read_mask_source(path, name: str = "masks") -> np.ndarray:
    """A mask stack from a ``.npy`` or ``.npz`` file (key ``masks``), one image, or a folder of
    images (sorted by name).

    A folder such as ``pacam optimize``'s ``lcos/`` holds one image per pattern
    (``pattern_00.png``, ``pattern_01.png``, ...), read in name order.
    """
    p = os.fspath(path)
    if os.path.isdir(p):
        images = sorted(
            os.path.join(p, f)
            for f in os.listdir(p)
            if os.path.splitext(f)[1].lower() in MASK_IMAGE_SUFFIXES
        )
        if not images:
            raise ParameterError(
                f"{name}: folder {p!r} holds no mask images ({', '.join(MASK_IMAGE_SUFFIXES)})"
            )
        return load_masks(",".join(images), name)
    if not os.path.isfile(p):
        raise ParameterError(f"{name}: no such file or folder {p!r}")
    return load_masks(p, name)


MASK_IMAGE_SUFFIXES = (".png", ".bmp", ".tif", ".tiff", ".exr", ".jpg", ".jpeg", ".pgm")
"""Image files that a folder of LCoS bitmaps may hold."""


class MaskStack:
    """An immutable LCoS bitmap schedule: N transmittance patterns and the display's pitch.

    Two stacks are equal when their patterns and pitch are (compared by :attr:`digest`), so a
    :class:`~pacam_render.model.camera.CameraDesign` holding one stays a value.

    Parameters
    ----------
    masks : array-like
        ``(N, H, W)`` transmittances in [0, 1] (see the module's orientation convention).
    pitch_mm : float
        The display's pixel pitch, mm.
    source : str, optional
        Where the stack was read from (information only: not compared).
    name : str, optional
        What the messages call the masks (a design file's ``[schedule] masks``).
    """

    __slots__ = ("array", "pitch_mm", "digest", "source", "name", "_memo")

    def __init__(
        self, masks, pitch_mm: float = LCOS_PITCH_MM, source: str | None = None, name="masks"
    ):
        a = load_masks(masks, name)
        a.setflags(write=False)
        pitch = check_positive("mask_pitch_mm", pitch_mm, "mm")
        h = hashlib.sha256(np.ascontiguousarray(a).tobytes())
        h.update(repr((a.shape, float(pitch))).encode())
        object.__setattr__(self, "array", a)
        object.__setattr__(self, "pitch_mm", float(pitch))
        object.__setattr__(self, "digest", h.hexdigest()[:16])
        object.__setattr__(self, "source", source)
        object.__setattr__(self, "name", name)  # information only, as source
        object.__setattr__(self, "_memo", {})  # figures of the patterns, computed once
        if isinstance(masks, np.ndarray) and masks.dtype == np.uint8 and masks.shape == a.shape:
            codes = masks.copy()  # 8-bit levels, as a file stores them: compact_array's
            codes.setflags(write=False)
            self._memo["codes"] = codes

    def __setattr__(self, key, value):
        raise AttributeError("MaskStack is immutable")

    def __eq__(self, other) -> bool:
        return isinstance(other, MaskStack) and other.digest == self.digest

    def __hash__(self) -> int:
        return hash(self.digest)

    def __repr__(self) -> str:
        n, h, w = self.array.shape
        return f"MaskStack({n} x {h}x{w}, pitch {self.pitch_mm:g} mm, digest {self.digest})"

    def __deepcopy__(self, memo):  # immutable: dataclasses.asdict copies fields deeply
        return self

    def __reduce__(self):  # pickled (to Dask workers) as its constructor's arguments
        return (MaskStack, (np.asarray(self.array), self.pitch_mm, self.source, self.name))

    @property
    def n_patterns(self) -> int:
        return int(self.array.shape[0])

    def check_inside(self, lens_radius_mm: float) -> None:
        """:func:`check_masks` for a lens of radius ``lens_radius_mm``; the patterns' reach is
        measured once per stack (a design is checked on every copy)."""
        reach2 = self.once("reach2", lambda: open_reach2_mm2(self.array, self.pitch_mm))
        check_masks(self.array, lens_radius_mm, self.pitch_mm, reach2)

    def check_open(self, where: str | None = None) -> None:
        """Raise unless some pattern passes light, naming the masks (``where``, else the name
        they were read under) and their source: an all-black stack has no opening, and its
        radius of 0 would be refused as an R_mm that says nothing of the masks."""
        if not self.once("open", lambda: bool(np.any(self.array > 0))):
            src = f" ({self.source})" if self.source else ""
            raise ParameterError(
                f"{where or self.name}{src}: the masks are all black: no light passes "
                f"(transmittance 0 in every pattern); open some pixels"
            )

    def once(self, name: str, compute):
        """``compute()``, kept: the stack is immutable, and a capture's record, checks and
        schedule figures ask for the same figures of its (often 84 MB of) patterns."""
        if name not in self._memo:
            value = compute()
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            self._memo[name] = value
        return self._memo[name]

    def open_areas_mm2(self) -> np.ndarray:
        """Each pattern's open area, sum(tau) pitch^2, mm^2, shape (N,)."""
        area = lambda: self.array.sum(axis=(1, 2), dtype=np.float64) * self.pitch_mm**2  # noqa: E731
        return self.once("areas", area).copy()

    def centroids_xy_mm(self) -> np.ndarray:
        """Each pattern's transmittance-weighted centre (x right, y down), mm, shape (N, 2);
        NaN for an all-black pattern."""
        return self.once("centroids", self._centroids).copy()

    def _centroids(self) -> np.ndarray:
        n, h, w = self.array.shape
        x = (np.arange(w) + 0.5 - w / 2.0) * self.pitch_mm
        y = (np.arange(h) + 0.5 - h / 2.0) * self.pitch_mm
        tot = self.array.sum(axis=(1, 2), dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            cx = self.array.sum(axis=1, dtype=np.float64) @ x / tot
            cy = self.array.sum(axis=2, dtype=np.float64) @ y / tot
        return np.stack([cx, cy], axis=1)

    def equivalent_radius_mm(self) -> float:
        """The radius of a disc with the patterns' mean open area, mm (what a still mode
        opens, so that every 2T mode collects the same light); refused for all-black masks."""
        self.check_open()
        return float(np.sqrt(self.open_areas_mm2().mean() / np.pi))

    def compact_array(self) -> np.ndarray:
        """The patterns as 8-bit code values when that is exact (binary masks, images),
        else float32: what a file stores, and :func:`load_masks` reads back identically."""
        if "codes" in self._memo:  # made from 8-bit levels (a design file's stack)
            return self._memo["codes"]
        a = self.array
        codes = (a * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)  # a in [0, 1]
        if np.array_equal(code_levels(codes), a):  # as load_masks reads 8-bit levels
            return codes
        return a.astype("<f4")

    def to_json(self) -> dict:
        """The stack, exactly, JSON-ready: the patterns as zlib-compressed, base64 bytes
        (8-bit code values when every transmittance is one, else float32). Compressed once
        per stack (64 full-display masks take 1.5 s): every record of a capture embeds it."""
        return dict(self.once("json", self._encode))

    def _encode(self) -> dict:
        data = self.compact_array()
        return {
            "shape": list(data.shape),
            "dtype": "uint8" if data.dtype == np.uint8 else "float32",
            "pitch_mm": self.pitch_mm,
            "digest": self.digest,
            "zlib_base64": base64.b64encode(zlib.compress(data.tobytes(), 9)).decode("ascii"),
            **({"source": self.source} if self.source else {}),
        }

    @classmethod
    def from_json(cls, d: dict, where: str = "pattern_masks") -> MaskStack:
        """The stack that :meth:`to_json` wrote; its digest must match."""
        try:
            shape = tuple(int(v) for v in d["shape"])
            dtype = {"uint8": np.uint8, "float32": np.dtype("<f4")}[d["dtype"]]
            blob = base64.b64decode(d["zlib_base64"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ParameterError(f"{where}: not a stored mask stack ({exc})") from None
        _check_declared(shape, dtype, d.get("digest"), where)  # before anything inflates
        raw = _inflate(blob, shape, dtype, where)
        try:
            a = np.frombuffer(raw, dtype=dtype).reshape(shape)
            pitch = float(d["pitch_mm"])
        except (KeyError, TypeError, ValueError, zlib.error) as exc:
            raise ParameterError(f"{where}: not a stored mask stack ({exc})") from None
        stack = cls(a, pitch, d.get("source"), where)
        if d.get("digest") not in (None, stack.digest):
            raise ParameterError(
                f"{where}: the patterns do not match their digest ({d['digest']} recorded, "
                f"{stack.digest} read): the record was edited or damaged"
            )
        return stack


MAX_STACK_BYTES = 256 * 2**20
"""The most a stored mask stack may inflate to (256 MiB: 256 patterns of the prototype's
1024 x 1024 LCoS disc, uint8)."""


def _check_declared(shape: tuple, dtype, digest, where: str) -> None:
    """A stored stack's declared shape and digest, checked before anything is inflated."""

    if len(shape) != 3 or min(shape) < 1:
        raise ParameterError(f"{where}: shape must be (patterns, rows, columns), got {shape}")
    if shape[0] > MAX_PATTERNS:
        raise ParameterError(f"{where}: {shape[0]} patterns, over {MAX_PATTERNS}")
    size = int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
    if size > MAX_STACK_BYTES:
        raise ParameterError(
            f"{where}: declares {shape} ({size / 2**20:.0f} MiB), over the "
            f"{MAX_STACK_BYTES // 2**20} MiB a stack may take"
        )
    if not isinstance(digest, str):
        raise ParameterError(f"{where}: the stack's digest is missing: the record was edited")


def _inflate(blob: bytes, shape: tuple, dtype, where: str) -> bytes:
    """zlib-inflate at most the declared size (a bomb stops there)."""
    want = int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
    d = zlib.decompressobj()
    try:
        raw = d.decompress(blob, want + 1)
    except zlib.error as exc:
        raise ParameterError(f"{where}: the stored patterns are not zlib data ({exc})") from None
    if len(raw) != want or d.unconsumed_tail:
        raise ParameterError(
            f"{where}: the stored patterns do not inflate to their declared shape {shape}"
        )
    return raw


_STACKS: dict = {}  # (path, pitch, what the files were) -> MaskStack, the last few read
_STACKS_KEPT = 4


def _file_state(path: str) -> tuple:
    """What a mask source was when read: each file's name, size and modification time."""
    if os.path.isdir(path):
        names = sorted(os.listdir(path))
        return tuple((n, *_stat(os.path.join(path, n))) for n in names)
    return (_stat(path),)


def _stat(path: str) -> tuple:
    try:
        st = os.stat(path)
    except OSError:
        return (None, None)
    return (st.st_size, st.st_mtime_ns)


def read_mask_stack(path, pitch_mm: float, source: str | None = None, name: str = "masks"):
    """:class:`MaskStack` of :func:`read_mask_source`, read once per process while its files are
    unchanged (size and modification time): a command reads its design more than once, and 64
    full-display masks take 1-2 s to read, decode and hash."""
    p = os.path.abspath(os.fspath(path))
    key = (p, float(pitch_mm), source, _file_state(p))
    stack = _STACKS.get(key)
    if stack is None:
        stored = os.path.isfile(p) and p.lower().endswith((".npz", ".npy"))
        raw = _load_file(p, name) if stored else read_mask_source(path, name)  # levels kept
        stack = MaskStack(raw, pitch_mm, source, name)
        if len(_STACKS) >= _STACKS_KEPT:
            _STACKS.pop(next(iter(_STACKS)))
        _STACKS[key] = stack
    return stack
