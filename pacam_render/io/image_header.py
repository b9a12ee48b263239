"""An image file's size from its header alone, before anything decodes it.

A PNG of 3.5 MB may declare 60000 x 60000 px: Mitsuba's decoder then takes 40 s and 3.35 GiB
for an LCoS mask, and a scene texture that size ends the render with a segfault. So a file a
user names is measured here first, and refused above a bound, without reading a pixel.

The formats are Mitsuba's (``mi.Bitmap``), recognised as Mitsuba recognises them: by their
first bytes (PNG, JPEG, OpenEXR, Radiance RGBE, PFM, binary PPM, BMP), a TGA by its version-2
footer. Pillow is not used: its own bomb guard (above 179 Mpx) gives a pixel count, not the
sides, it reads no RGBE, and it recognises files that Mitsuba does not.
"""

from __future__ import annotations

import os
import stat
import struct

from ..errors import ParameterError
from .exr import read_layer_shapes

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
EXR_MAGIC = b"\x76\x2f\x31\x01"
TGA_FOOTER = b"TRUEVISION-XFILE.\0"
_JPEG_SOF = {*range(0xC0, 0xD0)} - {0xC4, 0xC8, 0xCC}  # frame headers; C4/C8/CC are not
_JPEG_STANDALONE = {0x01, *range(0xD0, 0xD8)}  # markers without a length
MAX_JPEG_SEGMENTS = 4096
"""Segments read before a JPEG's frame header (real files have tens: APPn, DQT, DHT)."""
MAX_TEXT_HEADER = 65536
"""Bytes of a text header (RGBE, PFM, PPM) read to find the size (real ones take < 200)."""


def image_size(path) -> tuple[int, int] | None:
    """The (width, height) an image file declares, read from its header only.

    Parameters
    ----------
    path : path-like
        A file Mitsuba may read as an image.

    Returns
    -------
    tuple of int or None
        (width, height) in pixels; None for what is not a regular file, is in no format
        Mitsuba reads, or has a header too broken to give a size (Mitsuba's decoder then
        refuses it with its own message).

    Raises
    ------
    ParameterError
        A JPEG with more than :data:`MAX_JPEG_SEGMENTS` segments before its frame header, or
        an OpenEXR file whose header is unreadable.
    """
    p = os.fspath(path)
    try:
        if not stat.S_ISREG(os.stat(p).st_mode):
            return None
        with open(p, "rb") as fh:
            head = fh.read(32)
            if head.startswith(PNG_SIGNATURE):
                return _png(head)
            if head.startswith(b"\xff\xd8"):
                return _jpeg(fh, p)
            if head.startswith(EXR_MAGIC):
                shapes = read_layer_shapes(p)
                return None if not shapes else _wh(next(iter(shapes.values()))[:2][::-1])
            if head.startswith(b"#?"):
                return _rgbe(head + fh.read(MAX_TEXT_HEADER))
            if head[:2] in (b"PF", b"Pf", b"P6"):
                return _pnm(head + fh.read(MAX_TEXT_HEADER))
            if head.startswith(b"BM"):
                return _bmp(head)
            return _tga(fh, head)
    except OSError:
        return None  # unreadable: the decoder says why


def check_image_size(path, max_side_px: int, what: str, whose: str) -> tuple[int, int] | None:
    """Refuse an image file wider or taller than ``max_side_px``, from its header.

    Parameters
    ----------
    path : path-like
        The image file.
    max_side_px : int
        The largest width and height accepted.
    what, whose : str
        The file's place and what the bound is for, in the message: ``"{what}: {path} declares
        W x H px, over the {max_side_px} px a side {whose}; ..."``.

    Returns
    -------
    tuple of int or None
        :func:`image_size`'s answer.

    Raises
    ------
    ParameterError
        If the file declares a side over ``max_side_px``.
    """
    size = image_size(path)
    if size is not None and max(size) > max_side_px:
        w, h = size
        raise ParameterError(
            f"{what}: {os.fspath(path)!r} declares {w} x {h} px, over the {max_side_px} px a "
            f"side {whose}; it was not decoded"
        )
    return size


def _wh(wh) -> tuple[int, int]:
    return int(wh[0]), int(wh[1])


def _png(head: bytes) -> tuple[int, int] | None:
    # the first chunk is IHDR (libpng refuses a file without it): length, type, width, height
    if len(head) < 24 or head[12:16] != b"IHDR":
        return None
    return _wh(struct.unpack(">II", head[16:24]))


def _jpeg(fh, path: str) -> tuple[int, int] | None:
    """The frame header's size, found as libjpeg finds it: segment by segment, skipping bytes
    between segments (libjpeg warns of them and reads on) and fill bytes."""
    fh.seek(2)
    for _ in range(MAX_JPEG_SEGMENTS):
        b = _next_ff(fh)
        while b == b"\xff":
            b = fh.read(1)
        if not b:
            return None
        marker = b[0]
        if marker in _JPEG_SOF:  # length (2), precision (1), height (2), width (2)
            seg = fh.read(7)
            return None if len(seg) < 7 else _wh(struct.unpack(">HH", seg[3:7])[::-1])
        if marker in (0xD9, 0xDA):  # the image ends, or its scan starts, before a frame
            return None
        if marker in _JPEG_STANDALONE:
            continue
        n = fh.read(2)
        if len(n) < 2:
            return None
        fh.seek(struct.unpack(">H", n)[0] - 2, os.SEEK_CUR)
    raise ParameterError(
        f"{path!r} has over {MAX_JPEG_SEGMENTS} JPEG segments before its frame header: not an "
        "image to read"
    )


def _next_ff(fh) -> bytes:
    """Read up to the next 0xFF byte (returned) or the end (b"")."""
    while True:
        chunk = fh.read(1)
        if chunk in (b"\xff", b""):
            return chunk
        block = fh.read(65536)  # bytes between segments: find the next 0xFF in blocks
        i = block.find(b"\xff")
        if i >= 0:
            fh.seek(i - len(block) + 1, os.SEEK_CUR)
            return b"\xff"
        if not block:
            return b""


def _rgbe(text: bytes) -> tuple[int, int] | None:
    # header lines, an empty line, then the resolution line: "-Y 512 +X 768" (Y first: rows)
    _, sep, rest = text.partition(b"\n\n")
    tokens = rest.split(b"\n", 1)[0].split()
    if not sep or len(tokens) != 4 or not (tokens[1].isdigit() and tokens[3].isdigit()):
        return None
    a, b = int(tokens[1]), int(tokens[3])
    return (b, a) if tokens[0][-1:] == b"Y" else (a, b)


def _pnm(text: bytes) -> tuple[int, int] | None:
    # "P6" / "PF" / "Pf", then width and height as text; PPM comments start with '#'
    lines = [ln.split(b"#", 1)[0] for ln in text[2:].split(b"\n")]
    tokens = b" ".join(lines).split()[:2]
    if len(tokens) < 2 or not all(t.isdigit() for t in tokens):
        return None
    return int(tokens[0]), int(tokens[1])


def _bmp(head: bytes) -> tuple[int, int] | None:
    if len(head) < 26:
        return None
    if struct.unpack("<I", head[14:18])[0] == 12:  # OS/2 core header: 16-bit sides
        return _wh(struct.unpack("<HH", head[18:22]))
    w, h = struct.unpack("<ii", head[18:26])
    return abs(w), abs(h)  # a negative height is a top-down image


def _tga(fh, head: bytes) -> tuple[int, int] | None:
    # Mitsuba takes a file for a TGA by its version-2 footer only; the sides are at 12 and 14
    fh.seek(0, os.SEEK_END)
    if fh.tell() < 18 + 26 or len(head) < 16:
        return None
    fh.seek(-18, os.SEEK_END)
    if fh.read(18) != TGA_FOOTER:
        return None
    return _wh(struct.unpack("<HH", head[12:16]))
