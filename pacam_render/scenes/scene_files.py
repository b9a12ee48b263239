"""The files a Mitsuba scene XML names, checked before Mitsuba loads it (issue 47, high 10).

Mitsuba reads whatever a ``filename`` names: a ``ply`` shape pointed at ``/dev/zero`` read
for 99 s up to 17 GB before it failed. So every file a scene names (a shape's or a texture's
``<string name="filename" value="..."/>``, an ``<include filename="..."/>``) must be a regular
file of at most :data:`MAX_ASSET_BYTES`, and the XML itself at most :data:`MAX_SCENE_XML_BYTES`,
before anything is read. A name that does not exist is left to Mitsuba, which says so.

An image is also measured from its header (issue 56): a 0.4 MB PNG texture declaring
60000 x 60000 px ended the render with a segfault and no message.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from ..errors import ParameterError
from ..io.image_header import check_image_size
from ..limits import note

MAX_SCENE_XML_BYTES = 64 * 2**20
"""The largest scene XML read (64 MiB; the built-in scenes' are under 20 KiB)."""
MAX_ASSET_BYTES = 4 * 2**30
"""The largest mesh or texture file a scene may name (4 GiB: a 100-million-triangle PLY)."""
MAX_TEXTURE_SIDE_PX = 16384
"""The widest or tallest image a scene may name: the largest texture side GPUs take
(Direct3D 11 and 12, most Vulkan devices) and the width of the largest environment maps in
common use (16K, 16384 x 8192). A 16384 x 16384 RGB texture is 3 GiB as Mitsuba's float32."""


def check_scene_xml_size(path: Path) -> None:
    """Refuse a scene XML over :data:`MAX_SCENE_XML_BYTES` before reading it."""
    size = path.stat().st_size
    if size > MAX_SCENE_XML_BYTES:
        raise ParameterError(
            f"scene file {str(path)!r} is {size / 2**20:.0f} MiB, over the "
            f"{MAX_SCENE_XML_BYTES // 2**20} MiB a scene XML may take"
        )


def named_files(text: str) -> list[tuple[str, bool]]:
    """The file names a scene XML's elements give, as written, each with whether it is an
    ``<include>``; [] when it does not parse (Mitsuba then reports the error itself)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return []
    out = []
    for el in root.iter():
        if el.tag == "string" and el.get("name") == "filename" and el.get("value"):
            out.append((el.get("value"), False))
        elif el.tag == "include" and el.get("filename"):
            out.append((el.get("filename"), True))
    return out


def xml_defaults(text: str) -> dict[str, str]:
    """The ``<default name="..." value="..."/>`` values of a scene XML: what its ``$name``
    references take when the caller gives no value ({} when it does not parse)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return {}
    return {
        el.get("name"): el.get("value", "")
        for el in root.iter("default")
        if el.get("name") is not None
    }


def check_scene_files(path: Path, text: str, params: dict) -> None:
    """Refuse a file the scene ``path`` names that is not a regular file (a device, a pipe,
    a folder) or is over :data:`MAX_ASSET_BYTES`, an image that declares a side over
    :data:`MAX_TEXTURE_SIDE_PX` (read from its header, before anything decodes it), and an
    ``<include>`` that is not ``.xml``; note one that lies outside the scene's folder (written
    so, not through a ``$name`` parameter). ``params``, else the scene's ``<default>`` values,
    fill its ``$name`` references, as Mitsuba does."""
    values = {**xml_defaults(text), **params}
    for written, include in named_files(text):
        name = re.sub(r"\$(\w+)", lambda m: str(values.get(m.group(1), m.group(0))), written)
        f = Path(name)
        f = f if f.is_absolute() else path.parent / f
        if include and f.suffix.lower() != ".xml":
            raise ParameterError(
                f"scene file {str(path)!r} includes {written!r}, which is not a .xml scene file"
            )
        outside = not os.path.abspath(f).startswith(os.path.abspath(path.parent) + os.sep)
        if outside and "$" not in written:
            note(f"scene file {path.name} reads {written!r}, outside its folder ({f})")
        try:
            st = os.stat(f)
        except OSError:
            continue  # Mitsuba looks further (its file resolver) and names what is missing
        what = f"scene file {str(path)!r} names {written!r} ({f})"
        if not stat.S_ISREG(st.st_mode):
            raise ParameterError(
                f"{what}, which is not a regular file (a device, a pipe or a folder): a scene "
                "reads its meshes and textures from files"
            )
        if st.st_size > MAX_ASSET_BYTES:
            raise ParameterError(
                f"{what}, of {st.st_size / 2**30:.1f} GiB, over the "
                f"{MAX_ASSET_BYTES // 2**30} GiB a scene's mesh or texture may take"
            )
        if not include:  # an image by its content, as Mitsuba tells one (not by its suffix)
            whose = "a scene's texture may have (the largest GPU textures and 16K maps)"
            check_image_size(
                f, MAX_TEXTURE_SIDE_PX, f"scene file {str(path)!r} names {written!r}", whose
            )
