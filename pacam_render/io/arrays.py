"""Files of numbers from elsewhere, read once and refused cleanly: ``.npy`` arrays (never
unpickled) and JSON documents (bounded in size and nesting)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ParameterError

MAX_JSON_BYTES = 64 * 2**20
"""The largest JSON document read (64 MiB: a capture's record with a 64-pattern bitmap stack
is under 2 MiB)."""


def read_npy(path, what: str) -> np.ndarray:
    """A real-valued, non-empty array from a ``.npy`` file; ``what`` names it in messages
    (``"`psf` file"``, ``"mask_file"``).

    Raises
    ------
    ParameterError
        If the file is missing, is not a ``.npy`` array (a truncated or foreign file), holds
        Python objects (it is never unpickled), strings, records or complex numbers, or is
        empty.
    """
    path = Path(path)
    if not path.is_file():  # a device, a folder or a pipe exists, but is no file to read
        why = "is not a regular file" if path.exists() else "does not exist"
        raise ParameterError(f"{what} {path} {why}")
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, EOFError, OSError) as exc:  # objects, truncated, or not a .npy file
        why = "holds Python objects" if "allow_pickle" in str(exc) else f"is not readable ({exc})"
        raise ParameterError(
            f"{what} {path} {why}; save it as numbers: np.save(path, np.asarray(a, dtype=float))"
        ) from None
    if not isinstance(a, np.ndarray) or a.dtype.kind not in "biuf":
        raise ParameterError(f"{what} {path} holds {a.dtype} values, not real numbers")
    if a.size == 0:
        raise ParameterError(f"{what} {path} holds an empty array (shape {a.shape})")
    return a


def read_json(path, what: str):
    """A JSON document, refused with one line (naming ``what`` and the file) when it is too
    large (:data:`MAX_JSON_BYTES`), not JSON, or nested too deep to parse."""
    path = Path(path)
    if not path.is_file():  # a device, a folder or a pipe exists, but is no file to read
        why = "is not a regular file" if path.exists() else "does not exist"
        raise ParameterError(f"{what} {path} {why}")
    try:
        size = path.stat().st_size
        if size > MAX_JSON_BYTES:
            raise ParameterError(
                f"{what} {path} is {size / 2**20:.0f} MiB, over the {MAX_JSON_BYTES // 2**20} "
                "MiB a record may take"
            )
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{what} {path} is not valid JSON ({exc})") from None
    except RecursionError:  # json's decoder recurses once per level: [[[...]]] 10^5 deep
        raise ParameterError(f"{what} {path} is nested too deep to read") from None
    except OSError as exc:
        raise ParameterError(f"{what} {path} cannot be read ({exc.strerror})") from None
