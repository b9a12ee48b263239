"""Deterministic textures of the built-in scenes (numpy + scikit-image): float RGB in [0, 1],
sRGB-encoded values, painted in mm on a texel grid into the atlases of :mod:`.meshes`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .meshes import (
    BOILER_H,
    BOILER_W,
    CAB_H,
    CAB_W,
    CAR_ATLAS,
    PANEL_H,
    PANEL_W,
    T_BALLAST,
    T_BLACK,
    T_BOILER,
    T_BRASS,
    T_CAB,
    T_CAR_BODY,
    T_CAR_CABIN,
    T_CAR_DARK,
    T_CAR_RED,
    T_CAR_WHEEL,
    T_DRIVER,
    T_FRAME,
    T_HEAD,
    T_PANEL,
    T_RAIL,
    T_RED,
    T_ROOF,
    T_SHIRT,
    T_SHOE,
    T_SKIN,
    T_SLEEPER,
    T_SLEEVE,
    T_STEEL,
    T_TROUSERS,
    T_WHEEL,
    TRACK_ATLAS,
    TRAIN_ATLAS,
    WALKER_ATLAS,
    Rect,
    sphere_dir,
    truncated_icosahedron_planes,
)

TEXELS_PER_MM = 6.0  # train-set panels: 6 texels/mm, about 2 texels per image px at 500 mm


# ============================================================================================
# Textures (float RGB in [0, 1], sRGB-encoded values, painted in mm on a texel grid)
# ============================================================================================
def _rgb(*c: int) -> np.ndarray:
    return np.array(c, float) / 255.0


class _Canvas:
    """An image painted in mm (``d`` texels per mm); y grows downwards like PNG rows."""

    def __init__(self, w_px: int, h_px: int, colour, d: float = TEXELS_PER_MM):
        self.img = np.ones((h_px, w_px, 3)) * colour
        self.d = d
        self.y, self.x = (np.mgrid[0:h_px, 0:w_px] + 0.5) / d

    def paint(self, mask: np.ndarray, colour, alpha: float = 1.0) -> None:
        a = alpha * np.asarray(mask, float)[..., None]
        self.img = self.img * (1 - a) + a * np.asarray(colour, float)

    def rect(self, x0, y0, x1, y1) -> np.ndarray:
        return (self.x >= x0) & (self.x < x1) & (self.y >= y0) & (self.y < y1)

    def frame(self, x0, y0, x1, y1, t) -> np.ndarray:
        return self.rect(x0, y0, x1, y1) & ~self.rect(x0 + t, y0 + t, x1 - t, y1 - t)

    def disc(self, cx, cy, r) -> np.ndarray:
        return (self.x - cx) ** 2 + (self.y - cy) ** 2 < r * r

    def stamp(self, mask_img: np.ndarray, x0, y0, colour) -> None:
        """Blend a soft mask (values 0..1, texel units) with its top-left at (x0, y0) mm."""
        r0, c0 = round(y0 * self.d), round(x0 * self.d)
        h, w = mask_img.shape
        sub = self.img[r0 : r0 + h, c0 : c0 + w]
        a = mask_img[: sub.shape[0], : sub.shape[1], None]
        self.img[r0 : r0 + h, c0 : c0 + w] = sub * (1 - a) + a * np.asarray(colour, float)


PAGE_LINES = (49, 66, 84, 101, 119)  # first rows of the body-text lines of skimage's ``page``
PAGE_TITLE = (12, 5)  # first row and column of its title line (23 rows tall)


def _text_mask(row: int, col: int, src_hw: tuple[int, int], out_hw: tuple[int, int]):
    """Soft lettering (0..1) cut from skimage's scanned ``page`` and resized to ``out_hw``."""
    from skimage import data, filters, transform

    t = data.page().astype(float)
    ink = np.clip((filters.threshold_local(t, 35, offset=10) - t) / 25.0, 0, 1)
    crop = ink[row : row + src_hw[0], col : col + src_hw[1]]
    return np.clip(transform.resize(crop, out_hw, order=1, anti_aliasing=True), 0, 1)


def _rivets(c: _Canvas, y, x0, x1, pitch=2.0, r=0.35, colour=(0.9, 0.85, 0.6)) -> None:
    m = np.zeros(c.x.shape, bool)
    for x in np.arange(x0, x1, pitch):
        m |= c.disc(x, y, r)
    c.paint(m, colour)


def _glass(c: _Canvas, x0, y0, x1, y1) -> None:
    """Dark window with diagonal reflection streaks and a light frame."""
    inside = c.rect(x0, y0, x1, y1)
    c.paint(inside, _rgb(32, 42, 58))
    streak = ((c.x + c.y) % 5.0) < 1.1
    c.paint(inside & streak, _rgb(110, 130, 150))
    c.paint(c.frame(x0, y0, x1, y1, 0.5), _rgb(215, 215, 205))


def coach_panel(base, band, letter, seed: int) -> np.ndarray:
    """Side of a coach, 95 x 28 mm: windows, doors, rivets, lettering, a 1 mm checker band;
    ``seed`` picks the line of text."""
    c = _Canvas(PANEL_W, PANEL_H, base)
    c.paint(c.rect(0, 3.5, 95, 13.8), band)
    for k in range(5):
        _glass(c, 13 + 14.5 * k, 5.0, 22 + 14.5 * k, 12.5)
    for x0 in (3.0, 84.0):  # doors: outline, small window, handle
        c.paint(c.frame(x0, 2.5, x0 + 7.5, 26.0, 0.35), _rgb(25, 20, 20))
        _glass(c, x0 + 1.8, 5.0, x0 + 5.7, 11.0)
        c.paint(c.disc(x0 + 6.2, 16.0, 0.45), _rgb(230, 200, 90))
    for y in (14.3, 21.2):
        c.paint(c.rect(0, y, 95, y + 0.4), letter)
    line = _text_mask(PAGE_LINES[seed % 5], 10 + 45 * seed % 190, (16, 176), (27, 300))
    c.stamp(line, 20.0, 15.4, letter)
    checks = ((np.floor(c.x) + np.floor(c.y)) % 2 == 0) & c.rect(0, 22.5, 95, 24.5)
    c.paint(c.rect(0, 22.5, 95, 24.5), _rgb(20, 20, 20))
    c.paint(checks, _rgb(235, 200, 40))
    _rivets(c, 1.3, 1.0, 95.0)
    _rivets(c, 26.7, 1.0, 95.0)
    c.paint(c.frame(0, 0, 95, 28, 0.4), np.asarray(base) * 0.45)
    return c.img


def cab_panel() -> np.ndarray:
    """Locomotive cab side, 30 x 34 mm: window, brass number plate, rivets."""
    c = _Canvas(CAB_W, CAB_H, _rgb(30, 70, 45))
    _glass(c, 8.0, 4.0, 22.0, 14.0)
    c.paint(c.rect(6.0, 18.5, 24.0, 24.5), _rgb(200, 160, 60))
    c.stamp(_text_mask(*PAGE_TITLE, (23, 75), (30, 100)), 7.0, 19.0, _rgb(20, 20, 20))
    for y in (1.5, 32.5):
        _rivets(c, y, 1.0, 30.0)
    c.paint(c.frame(0, 0, 30, 34, 0.5), _rgb(200, 160, 60))
    return c.img


def boiler_panel() -> np.ndarray:
    """Boiler, 62 x 22 mm: dark green with brass bands and rivet lines."""
    c = _Canvas(BOILER_W, BOILER_H, _rgb(25, 60, 40))
    for x in np.arange(4.0, 62.0, 12.0):
        c.paint(c.rect(x, 0, x + 0.9, 22), _rgb(210, 170, 70))
        m = np.zeros(c.x.shape, bool)
        for y in np.arange(1.0, 22.0, 1.6):
            m |= c.disc(x + 2.0, y, 0.3)
        c.paint(m, _rgb(120, 150, 120))
    c.paint(c.rect(0, 3.0, 62, 3.6), _rgb(140, 170, 140))
    return c.img


def wheel_image(n_spokes: int, counterweight: bool, n: int = 128) -> np.ndarray:
    """A spoked wheel face on a square: tyre, rim, spokes, hub."""
    y, x = (np.mgrid[0:n, 0:n] + 0.5) / n * 2 - 1
    r, phi = np.hypot(x, y), np.arctan2(y, x)
    img = np.ones((n, n, 3)) * _rgb(25, 25, 28)
    spoke = (np.abs(np.sin(n_spokes / 2 * phi)) < 0.16) & (r < 0.8)
    for mask, col in (
        (spoke, _rgb(170, 170, 175)),
        ((r > 0.78) & (r < 0.86), _rgb(190, 190, 195)),
        (r < 0.22, _rgb(200, 200, 205)),
        (r < 0.07, _rgb(40, 40, 40)),
    ):
        img[mask] = col
    if counterweight:
        img[(r < 0.75) & (r > 0.3) & (np.abs(phi + math.pi / 2) < 0.7)] = _rgb(150, 30, 30)
    return img


def _patch(atlas: np.ndarray, rect: Rect, img_or_colour) -> None:
    c0, r0, c1, r1 = (int(v) for v in rect)
    atlas[r0:r1, c0:c1] = img_or_colour


def train_texture(kind: str) -> np.ndarray:
    """Atlas of one train (see the ``T_*`` rectangles); ``kind`` is ``far`` or ``near``."""
    a = np.zeros((TRAIN_ATLAS.height, TRAIN_ATLAS.width, 3))
    if kind == "far":
        base, band, letter = _rgb(120, 25, 30), _rgb(120, 25, 30), _rgb(225, 185, 80)
    else:
        base, band, letter = _rgb(30, 60, 140), _rgb(235, 225, 190), _rgb(200, 30, 30)
    for k, rect in enumerate(T_PANEL):
        _patch(a, rect, coach_panel(base, band, letter, k + (3 if kind == "near" else 0)))
    _patch(a, T_CAB, cab_panel())
    _patch(a, T_BOILER, boiler_panel())
    _patch(a, T_WHEEL, wheel_image(8, False))
    _patch(a, T_DRIVER, wheel_image(12, True))
    for rect, col in (
        (T_ROOF, _rgb(60, 60, 65)),
        (T_FRAME, _rgb(35, 35, 38)),
        (T_RED, _rgb(170, 30, 25)),
        (T_STEEL, _rgb(150, 150, 155)),
        (T_BRASS, _rgb(210, 170, 70)),
        (T_BLACK, _rgb(20, 20, 20)),
    ):
        _patch(a, rect, col)
    return a


def _tinted(gray: np.ndarray, colour) -> np.ndarray:
    g = gray.astype(float) / 255.0
    return np.clip(g[..., None] * np.asarray(colour, float) / np.mean(g) * 0.5, 0, 1)


def track_texture() -> np.ndarray:
    """Gravel ballast (skimage ``gravel``, mirror-tiled), sleeper brown, rail steel."""
    from skimage import data

    a = np.zeros((TRACK_ATLAS.height, TRACK_ATLAS.width, 3))
    g = data.gravel()[:51]
    strip = np.concatenate([g if k % 2 == 0 else g[:, ::-1] for k in range(7)], axis=1)
    _patch(a, T_BALLAST, _tinted(strip[:, : TRACK_ATLAS.width], (0.62, 0.58, 0.52)))
    _patch(a, T_SLEEPER, _rgb(75, 50, 35))
    _patch(a, T_RAIL, _rgb(140, 135, 130))
    return a


def car_texture() -> np.ndarray:
    """Miniature car: red body with a checker stripe, number roundel, door, lights; cabin."""
    a = np.zeros((CAR_ATLAS.height, CAR_ATLAS.width, 3))
    body = _Canvas(600, 96, _rgb(200, 30, 30))
    stripe = body.rect(0, 2.0, 100, 4.0)
    body.paint(stripe, _rgb(245, 245, 245))
    body.paint(stripe & ((np.floor(body.x) + np.floor(body.y)) % 2 == 0), _rgb(15, 15, 15))
    body.paint(body.frame(32, 1.0, 68, 14.5, 0.3), _rgb(60, 10, 10))
    body.paint(body.rect(60, 7.0, 64, 7.8), _rgb(220, 220, 220))
    body.paint(body.disc(50, 8.5, 5.2), _rgb(245, 245, 245))
    body.stamp(_text_mask(*PAGE_TITLE, (23, 46), (24, 48)), 46.0, 6.5, _rgb(10, 10, 10))
    body.paint(body.rect(0.5, 5.0, 4.0, 8.0), _rgb(250, 230, 120))
    body.paint(body.rect(96, 5.0, 99.5, 8.0), _rgb(230, 40, 40))
    body.paint(body.rect(0, 14.0, 100, 16.0), _rgb(30, 30, 30))
    cab = _Canvas(300, 72, _rgb(200, 30, 30))
    _glass(cab, 4.0, 2.0, 23.5, 11.0)
    _glass(cab, 26.5, 2.0, 46.0, 11.0)
    _patch(a, T_CAR_BODY, body.img)
    _patch(a, T_CAR_CABIN, cab.img)
    _patch(a, T_CAR_WHEEL, wheel_image(5, False))
    _patch(a, T_CAR_RED, _rgb(200, 30, 30))
    _patch(a, T_CAR_DARK, _rgb(20, 20, 20))
    return a


BACKDROP_PHOTOS = ("chelsea", "astronaut", "coffee", "rocket", "stereo_motorcycle", "camera")
BACKDROP_GRID = (3, 2)  # columns, rows
BACKDROP_CELL_PX = (512, 576)  # width, height: 1536 x 1152 in all, ~3.1 texels/mm


def backdrop_texture() -> np.ndarray:
    """A collage of six scikit-image photographs (shipped offline), framed by 4-px borders."""
    from skimage import data, transform

    cw, ch = BACKDROP_CELL_PX
    cols, rows = BACKDROP_GRID
    out = np.zeros((rows * ch, cols * cw, 3))
    for k, name in enumerate(BACKDROP_PHOTOS):
        img = getattr(data, name)()
        img = img[0] if name == "stereo_motorcycle" else img
        img = np.repeat(img[..., None], 3, -1) if img.ndim == 2 else img
        h, w = img.shape[:2]
        scale = max(ch / h, cw / w)  # crop the centre to the cell's aspect
        hh, ww = round(ch / scale), round(cw / scale)
        img = img[(h - hh) // 2 : (h - hh) // 2 + hh, (w - ww) // 2 : (w - ww) // 2 + ww]
        cell = transform.resize(img / 255.0, (ch, cw), order=1, anti_aliasing=True)
        cell[:4], cell[-4:], cell[:, :4], cell[:, -4:] = 0.05, 0.05, 0.05, 0.05
        r, c = divmod(k, cols)
        out[r * ch : (r + 1) * ch, c * cw : (c + 1) * cw] = cell
    return out


def ball_texture(w: int = 1024) -> np.ndarray:
    """Equirectangular football: black pentagons, white hexagons, dark seams."""
    n, d = truncated_icosahedron_planes()
    h = w // 2
    v, u = (np.mgrid[0:h, 0:w] + 0.5) / np.array([h, w])[:, None, None]
    dirs = sphere_dir(math.pi * v, 2 * math.pi * u)
    score = (dirs @ n.T) / d  # central projection hits the plane with the largest score first
    order = np.sort(score, axis=-1)
    best = np.argmax(score, axis=-1)
    img = np.where((best < 12)[..., None], _rgb(20, 20, 22), _rgb(235, 235, 228))
    seam = (order[..., -1] - order[..., -2]) < 0.012 * order[..., -1]
    img[seam] = _rgb(70, 70, 70)
    return img


def walker_texture() -> np.ndarray:
    """Tartan shirt (8 mm checks, high frequency), denim trousers, head with hair, skin."""
    a = np.zeros((WALKER_ATLAS.height, WALKER_ATLAS.width, 3))
    y, x = np.mgrid[0:512, 0:512].astype(float)
    tartan = np.zeros((512, 512, 3)) + _rgb(40, 70, 130)
    for per, wid, col in ((16, 5, _rgb(180, 40, 40)), (32, 3, _rgb(230, 210, 90))):
        tartan[(x % per < wid) | (y % per < wid)] = col
    tartan[(x % 16 < 5) & (y % 16 < 5)] = _rgb(90, 20, 25)
    _patch(a, T_SHIRT, tartan)
    rng = np.random.default_rng(7)
    twill = ((x + y) % 6 < 3) * 0.12 + rng.random((512, 512)) * 0.15
    _patch(a, T_TROUSERS, _rgb(35, 55, 95) * (0.8 + twill[..., None]))
    head = np.zeros((256, 256, 3)) + _rgb(225, 180, 150)
    head[:90] = _rgb(60, 40, 25)
    head[90:140, -70:] = _rgb(60, 40, 25)  # back of the head: -x, the image's right
    _patch(a, T_HEAD, head)
    _patch(a, T_SKIN, _rgb(225, 180, 150))
    _patch(a, T_SHOE, _rgb(30, 25, 20))
    sleeve = np.zeros((212, 256, 3)) + _rgb(40, 70, 130)
    sleeve[(np.mgrid[0:212, 0:256][0] % 16) < 5] = _rgb(180, 40, 40)
    _patch(a, T_SLEEVE, sleeve)
    return a


def tile_texture(name: str, colour) -> np.ndarray:
    """A tinted grey scikit-image texture (``brick``, ``grass``) for repeating walls/floors."""
    from skimage import data

    return _tinted(getattr(data, name)(), colour)


def textures() -> dict[str, Callable[[], np.ndarray]]:
    """Texture builders by file stem (each returns float RGB in [0, 1], sRGB-encoded)."""
    return {
        "far_train": lambda: train_texture("far"),
        "near_train": lambda: train_texture("near"),
        "track": track_texture,
        "car": car_texture,
        "backdrop": backdrop_texture,
        "soccer_ball": ball_texture,
        "walker": walker_texture,
        "brick": lambda: tile_texture("brick", (0.75, 0.42, 0.32)),
        "grass": lambda: tile_texture("grass", (0.35, 0.55, 0.25)),
    }
