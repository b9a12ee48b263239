"""Multi-layer float32 OpenEXR files: layer "name" holds channels name.R/G/B, name.Y for a
single-channel layer, or name.U/V for a two-channel one (a velocity).
Reading a missing or corrupt file, or a missing layer, is a clear error."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import ParameterError
from .outputs import atomic_save

RGB = ("R", "G", "B")
UV = ("U", "V")


def _channels(layers: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    out = {}
    for name, arr in layers.items():
        a = np.asarray(arr)
        if not np.all(np.isfinite(a)):
            raise ParameterError(f"layer {name!r} contains NaN or infinite values; not written")
        a = np.ascontiguousarray(a, dtype=np.float32)
        if a.ndim == 2:
            out[f"{name}.Y"] = a
        elif a.ndim == 3 and a.shape[2] == 3:
            for c, ch in enumerate(RGB):
                out[f"{name}.{ch}"] = np.ascontiguousarray(a[..., c])
        elif a.ndim == 3 and a.shape[2] == 1:
            out[f"{name}.Y"] = np.ascontiguousarray(a[..., 0])
        elif a.ndim == 3 and a.shape[2] == 2:
            for c, ch in enumerate(UV):
                out[f"{name}.{ch}"] = np.ascontiguousarray(a[..., c])
        else:
            raise ParameterError(
                f"layer {name!r} must be (H, W), (H, W, 1), (H, W, 2) or (H, W, 3), got {a.shape}"
            )
    return out


def write_exr(path: str | os.PathLike, layers: dict[str, np.ndarray], force: bool = False) -> Path:
    """Write float32 layers atomically (temporary file + rename)."""
    import OpenEXR

    chans = _channels(layers)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def save(tmp: str) -> None:
        with OpenEXR.File(header, dict(chans)) as f:  # OpenEXR replaces the dict's arrays: copy
            try:
                f.write(tmp)
            except RuntimeError as exc:  # OpenEXR reports a full disk so: say it as the OS does
                raise write_error(path, exc) from None

    return atomic_save(path, save, force)


def write_error(path, exc: Exception) -> OSError:
    """A library's failed write (OpenEXR's or Mitsuba's ``RuntimeError``) as the ``OSError``
    the OS would raise, ``ENOSPC`` when its words say the disk is full, naming ``path``: the
    callers that keep a capture's passes on a failed write then see it as one."""
    import errno

    full = "no space left" in str(exc).lower()
    code = errno.ENOSPC if full else errno.EIO
    return OSError(code, f"{'no space left on device' if full else exc}", str(path))


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """All layers of an EXR, as float32 (H, W), (H, W, 2) or (H, W, 3) arrays."""
    import OpenEXR

    p = Path(path)
    if not p.is_file():
        raise ParameterError(f"EXR file {p} does not exist")
    try:
        with OpenEXR.File(str(p), separate_channels=True) as f:
            raw = {k: np.array(v.pixels, dtype=np.float32) for k, v in f.channels().items()}
    except Exception as exc:  # OpenEXR raises RuntimeError for corrupt files
        raise ParameterError(f"{p} is not a readable OpenEXR file ({exc})") from exc
    groups: dict[str, dict[str, np.ndarray]] = {}
    for key, arr in raw.items():
        layer, _, ch = key.rpartition(".")
        groups.setdefault(layer, {})[ch] = arr
    out = {}
    for layer, chans in groups.items():
        if set(RGB) <= set(chans):
            out[layer] = np.stack([chans[c] for c in RGB], axis=-1)
        elif set(chans) == set(UV):
            out[layer] = np.stack([chans[c] for c in UV], axis=-1)
        elif len(chans) == 1:
            out[layer] = next(iter(chans.values()))
        else:
            for ch, arr in chans.items():
                out[f"{layer}.{ch}" if layer else ch] = arr
    return out


def read_layer_shapes(path: str | os.PathLike) -> dict[str, tuple[int, ...]]:
    """The layers :func:`read_exr` would return and their shapes, from the header alone (no
    pixel is read): to check what reading and processing them will cost first.

    Parameters
    ----------
    path : path-like
        The EXR file.

    Returns
    -------
    dict
        Layer name to shape: (H, W, 3) for R/G/B, (H, W, 2) for U/V, (H, W) for one channel.

    Raises
    ------
    ParameterError
        If the file is missing or its header unreadable.
    """
    import OpenEXR

    p = Path(path)
    if not p.is_file():
        raise ParameterError(f"EXR file {p} does not exist")
    try:
        with OpenEXR.File(str(p), header_only=True) as f:
            header = f.header()
            (x0, y0), (x1, y1) = header["dataWindow"]
            names = [c.name for c in header["channels"]]
    except Exception as exc:  # OpenEXR raises RuntimeError for corrupt files
        raise ParameterError(f"{p} is not a readable OpenEXR file ({exc})") from exc
    hw = (int(y1 - y0 + 1), int(x1 - x0 + 1))
    groups: dict[str, set[str]] = {}
    for key in names:
        layer, _, ch = key.rpartition(".")
        groups.setdefault(layer, set()).add(ch)
    out: dict[str, tuple[int, ...]] = {}
    for layer, chans in groups.items():
        if set(RGB) <= chans:
            out[layer] = (*hw, 3)
        elif chans == set(UV):
            out[layer] = (*hw, 2)
        elif len(chans) == 1:
            out[layer] = hw
        else:
            out.update({f"{layer}.{ch}" if layer else ch: hw for ch in chans})
    return out


def read_layer(path: str | os.PathLike, name: str) -> np.ndarray:
    """One layer, or an error naming the layers the file has."""
    return pick_layer(read_exr(path), name, path)


def pick_layer(layers: dict[str, np.ndarray], name: str, path) -> np.ndarray:
    """Layer ``name`` of the already read ``layers`` of ``path``, or an error naming them."""
    if name not in layers:
        raise ParameterError(
            f"{path} has no layer {name!r}; it has: {', '.join(sorted(layers)) or '(none)'}"
        )
    return layers[name]
