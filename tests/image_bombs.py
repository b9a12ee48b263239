"""Decompression bombs for the tests of inputs measured before they decode (issue 56)."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path


def _chunk(kind: bytes, data: bytes) -> bytes:
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


def bomb_png(path: Path, side: int = 60_000) -> Path:
    """A valid black 1-bit greyscale PNG of ``side`` x ``side`` px, its zero rows streamed
    through zlib: at 60000 px, 0.4 MB on disk that Mitsuba decodes to 3.35 GiB (8-bit grey);
    about a second to write."""
    row = bytes(1 + (side + 7) // 8)  # filter byte 0, then the row's bits, all 0
    z = zlib.compressobj(9)
    rows_per_block = max(1, 2**20 // len(row))
    parts = []
    for start in range(0, side, rows_per_block):
        parts.append(z.compress(row * min(rows_per_block, side - start)))
    parts.append(z.flush())
    ihdr = struct.pack(">IIBBBBB", side, side, 1, 0, 0, 0, 0)  # 1 bit, grey, no interlace
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _chunk(b"IHDR", ihdr)
        + _chunk(b"IDAT", b"".join(parts))
        + _chunk(b"IEND", b"")
    )
    return path
