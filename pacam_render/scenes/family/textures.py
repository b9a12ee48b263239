"""Seeded textures for family scenes: procedural patterns drawn with numpy (checker, stripes,
smooth noise), or crops of scikit-image's bundled photographs (:data:`PHOTOS`), as 8-bit RGB
arrays, and a deterministic PNG writer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...io.outputs import atomic_save

OBJECT_TEXTURE_PX = 256
"""Side of an object's texture, texels."""
WALL_TEXTURE_PX = 512
"""Side of the wall's texture, texels."""

PROCEDURAL_KINDS = ("checker", "stripes", "noise")
"""The procedural patterns."""

PHOTOS = {
    "astronaut": "public domain (NASA): no known copyright restrictions",
    "brick": "CC0 (CC0Textures, Bricks25)",
    "camera": "CC0 (the photographer, Lav Varshney)",
    "cat": "CC0 (the photographer, Stefan van der Walt)",
    "chelsea": "CC0 (the photographer, Stefan van der Walt)",
    "coffee": "CC0 (the photographer, Rachel Michetti)",
    "grass": "CC0 (CC0Textures)",
    "gravel": "CC0 (CC0Textures, Gravel04)",
    "rocket": "public domain (SpaceX)",
}
"""scikit-image's bundled photographs the ``photos`` textures crop, with their licences as
scikit-image's docstrings state them (``skimage.data.<name>``)."""


def _colours(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Two colours, the second clearly lighter than the first (contrast for the deblurring)."""
    dark = rng.uniform(0.05, 0.45, 3)
    light = rng.uniform(0.55, 0.95, 3)
    return dark, light


def _blend(mask: np.ndarray, dark: np.ndarray, light: np.ndarray) -> np.ndarray:
    return dark + mask[..., None] * (light - dark)


def procedural_texture(rng: np.random.Generator, kind: str, n_px: int) -> np.ndarray:
    """A seeded ``kind`` pattern (:data:`PROCEDURAL_KINDS`), (n_px, n_px, 3) in [0, 1]."""
    dark, light = _colours(rng)
    yy, xx = np.mgrid[0:n_px, 0:n_px].astype(float)
    if kind == "checker":
        period = float(rng.uniform(12.0, 48.0))
        mask = ((np.floor(xx / period) + np.floor(yy / period)) % 2).astype(float)
    elif kind == "stripes":
        angle = float(rng.uniform(0.0, np.pi))
        period = float(rng.uniform(10.0, 40.0))
        phase = (xx * np.cos(angle) + yy * np.sin(angle)) / period
        mask = (phase % 1.0 < 0.5).astype(float)
    elif kind == "noise":
        mask = np.zeros((n_px, n_px))
        for _ in range(12):  # a sum of random plane waves: smooth, seeded, no filtering
            k = rng.uniform(-0.25, 0.25, 2)
            mask += np.cos(xx * k[0] + yy * k[1] + rng.uniform(0, 2 * np.pi))
        mask = (mask - mask.min()) / max(np.ptp(mask), 1e-12)
    else:
        raise ValueError(f"unknown procedural texture {kind!r}")
    return _blend(mask, dark, light)


def photo_texture(rng: np.random.Generator, name: str, n_px: int) -> np.ndarray:
    """A seeded square crop of scikit-image's ``name`` photograph, resized to n_px, RGB."""
    import skimage.data  # optional dependency: checked before any drawing (spec.photos_available)
    from PIL import Image

    img = np.asarray(getattr(skimage.data, name)())
    if img.ndim == 2:
        img = np.stack([img] * 3, -1)
    img = img[..., :3]
    h, w = img.shape[:2]
    side = int(min(h, w) * rng.uniform(0.4, 1.0))
    y0 = int(rng.integers(0, h - side + 1))
    x0 = int(rng.integers(0, w - side + 1))
    crop = Image.fromarray(np.ascontiguousarray(img[y0 : y0 + side, x0 : x0 + side]))
    crop = crop.resize((n_px, n_px), Image.Resampling.BILINEAR)
    return np.asarray(crop, dtype=float) / 255.0


def draw_texture(rng: np.random.Generator, source: str, n_px: int) -> tuple[np.ndarray, str]:
    """A texture from ``source`` (``procedural`` or ``photos``) and what it is, e.g.
    ``"checker"`` or ``"skimage:chelsea"``."""
    if source == "photos":
        name = sorted(PHOTOS)[int(rng.integers(len(PHOTOS)))]
        return photo_texture(rng, name, n_px), f"skimage:{name}"
    kind = PROCEDURAL_KINDS[int(rng.integers(len(PROCEDURAL_KINDS)))]
    return procedural_texture(rng, kind, n_px), kind


def write_png(path: Path, rgb: np.ndarray) -> Path:
    """Write an RGB image in [0, 1] as an 8-bit PNG, atomically; the same array gives the same
    bytes (fixed compression, no metadata)."""
    from PIL import Image

    u8 = np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
    return atomic_save(
        path,
        lambda tmp: Image.fromarray(u8).save(tmp, format="PNG", compress_level=6),
        force=True,
    )
