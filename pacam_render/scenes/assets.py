"""The asset cache of the built-in scenes: their meshes (:mod:`.meshes`, at the places of
:mod:`.layout`) written as binary PLY (trimesh, per-face ``s``/``t`` texcoords) and their
textures (:mod:`.textures`) as 8-bit sRGB PNG, with a manifest (sha256, bounds).

The assets (4.9 MB: 1.6 MB of PLY, 3.3 MB of PNG, mostly the photo collage) are too big to
commit, so they are built on first use (about 4 s) into ``$PACAM_CACHE`` (default
``~/.cache/pacam_render``), sub-folder ``assets-v<ASSET_VERSION>``, written into a temporary
folder and renamed, so concurrent processes never see half-written files. The same code gives
the same bytes (the tests check).

``python -m pacam_render.scenes.assets`` builds them and prints the folder.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .meshes import meshes, trimesh
from .textures import textures

ASSET_VERSION = 1


# ============================================================================================
# Files and the cache
# ============================================================================================
def cache_root() -> Path:
    """``$PACAM_CACHE`` or ``~/.cache/pacam_render``."""
    env = os.environ.get("PACAM_CACHE", "").strip()
    return Path(env).expanduser() if env else Path.home() / ".cache" / "pacam_render"


def asset_dir(root: Path | str | None = None) -> Path:
    """Folder that holds (or will hold) this version's assets."""
    return Path(root or cache_root()) / f"assets-v{ASSET_VERSION}"


def _write_png(path: Path, rgb: np.ndarray) -> None:
    from PIL import Image

    u8 = np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)
    Image.fromarray(u8).save(path, format="PNG", compress_level=6)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def build_assets(directory: Path | str) -> dict:
    """Write every mesh (PLY) and texture (PNG) into ``directory`` plus ``manifest.json``
    (sha256 and bounding box per file); return the manifest."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    files: dict[str, dict] = {}
    for name, mesh in meshes().items():
        p = d / f"{name}.ply"
        p.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary"))
        files[p.name] = {"bounds_mm": mesh.bounds.tolist(), "faces": len(mesh.faces)}
    for name, make in textures().items():
        p = d / f"{name}.png"
        _write_png(p, make())
        files[p.name] = {}
    for fname, info in files.items():
        info["sha256"] = _sha256(d / fname)
        info["bytes"] = (d / fname).stat().st_size
    manifest = {"asset_version": ASSET_VERSION, "files": files}
    (d / "manifest.json").write_text(json.dumps(manifest, indent=1, sort_keys=True))
    return manifest


def load_manifest(directory: Path | str) -> dict | None:
    """The manifest if ``directory`` holds a complete asset set, else None."""
    p = Path(directory) / "manifest.json"
    try:
        m = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    ok = m.get("asset_version") == ASSET_VERSION and all(
        (Path(directory) / f).is_file() for f in m.get("files", {})
    )
    return m if ok else None


def ensure_assets(root: Path | str | None = None) -> Path:
    """The asset folder, built on first use (atomically: temporary folder, then rename)."""
    final = asset_dir(root)
    if load_manifest(final) is not None:
        return final
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".assets-", dir=final.parent))
    try:
        build_assets(tmp)
        if load_manifest(final) is None:
            shutil.rmtree(final, ignore_errors=True)  # an incomplete earlier attempt
            try:
                tmp.rename(final)
            except OSError:  # another process won the race
                if load_manifest(final) is None:
                    raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return final


if __name__ == "__main__":
    print(ensure_assets())
