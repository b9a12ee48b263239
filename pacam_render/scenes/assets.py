"""Deterministic meshes and textures of the built-in scenes (trimesh + numpy + scikit-image).

Everything is in millimetres, in world coordinates, in the pose at t = 0 (mid-exposure): the
camera sits at the origin looking down +z (+y up; world +x shows on the image's *left*), so an
object at depth Z has z = Z. Meshes carry per-face UVs and are written as binary PLY (trimesh,
``s``/``t`` texcoords); textures as 8-bit sRGB PNG. UV convention (checked with a render): u, v
are PNG column / row fractions, v = 0 at the top row; a front face maps u = 0 to its largest x
so that textures read unmirrored in the image.

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
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

ASSET_VERSION = 1
TEXELS_PER_MM = 6.0  # train-set panels: 6 texels/mm, about 2 texels per image px at 500 mm

# --- Train-set layout (Section 4, Fig. 11): depth = z of the camera-facing (near) side -------
BACKDROP_Z_MM = 505.0
FAR_TRACK_Z_MM = 500.0
NEAR_TRACK_Z_MM = 495.0
CAR_Z_MM = 490.0
RELIEF_MM = 4.5  # the paper's 5 mm track spacing forces relief-like trains this deep
FAR_RAIL_Y_MM = 20.0  # far track on a raised embankment, so both trains are seen
NEAR_RAIL_Y_MM = -75.0
CAR_GROUND_Y_MM = -150.0
TRACK_HALF_LEN_MM = 260.0
UNIT_LEN_MM = 95.0
UNIT_GAP_MM = 5.0
FAR_TRAIN_X_MM = 15.0  # train centres at t = 0
NEAR_TRAIN_X_MM = -15.0
CAR_X_MM = 80.0  # +x: the image's left half
BACKDROP_SIZE_MM = (496.0, 372.0)  # covers the 46 deg view at 505 mm (428 x 321 mm)

# --- Other scenes -----------------------------------------------------------------------------
BALL_CENTRE_MM = (0.0, 0.0, 1000.0)
BALL_RADIUS_MM = 110.0  # a size-5 football
SOCCER_WALL_Z_MM = 1600.0
WALKER_Z_MM = 3000.0  # centre of the body
WALKER_WALL_Z_MM = 4500.0
WALKER_FLOOR_Y_MM = -900.0
HIP_Y_MM = 0.0
SHOULDER_Y_MM = 440.0
LEG_Z_OFFSET_MM = 100.0  # near leg at z = 3000 - 100
ARM_Z_OFFSET_MM = 235.0
LEG_SWING_DEG = 25.0  # pendulum gait: theta(t) = A sin(2 pi t / P + phase)
ARM_SWING_DEG = 18.0
GAIT_PERIOD_MS = 1100.0  # 1.8 steps/s
GAIT_PHASE_DEG = 45.0  # limbs apart and moving at mid-exposure

Rect = tuple[float, float, float, float]  # texel rectangle (col0, row0, col1, row1)


# ============================================================================================
# Mesh building
# ============================================================================================
@dataclass
class _Atlas:
    """Size of a texture atlas, to turn texel rectangles into normalised UV rectangles."""

    width: int
    height: int

    def uv(self, r: Rect) -> Rect:
        c0, r0, c1, r1 = r
        return (c0 / self.width, r0 / self.height, c1 / self.width, r1 / self.height)


@dataclass
class _Builder:
    """Concatenates primitives, each with its own per-face UV mapping into one atlas."""

    atlas: _Atlas
    verts: list[np.ndarray] = field(default_factory=list)
    faces: list[np.ndarray] = field(default_factory=list)
    uvs: list[np.ndarray] = field(default_factory=list)

    def add(self, mesh: trimesh.Trimesh, front: Rect, other: Rect | None = None) -> None:
        """Add ``mesh``: faces looking at the camera (-z) get ``front`` planar-mapped over the
        part's x-y extent; the others get ``other`` (a solid patch; default ``front``)."""
        v = mesh.vertices[mesh.faces].reshape(-1, 3)  # unshared: one UV per face corner
        facing = np.repeat(mesh.face_normals[:, 2] < -0.5, 3)
        lo, hi = mesh.bounds
        uv = np.empty((len(v), 2))
        uv[facing] = _planar(v[facing], lo, hi, self.atlas.uv(front))
        uv[~facing] = _planar(v[~facing], lo, hi, self.atlas.uv(other or front))
        base = sum(len(x) for x in self.verts)
        self.verts.append(v)
        self.faces.append(np.arange(len(v)).reshape(-1, 3) + base)
        self.uvs.append(uv)

    def mesh(self) -> trimesh.Trimesh:
        uv = np.concatenate(self.uvs)
        return trimesh.Trimesh(
            np.concatenate(self.verts),
            np.concatenate(self.faces),
            visual=trimesh.visual.TextureVisuals(uv=uv),
            process=False,  # processing would merge vertices and lose the UV seams
        )


def _planar(v: np.ndarray, lo: np.ndarray, hi: np.ndarray, r: Rect) -> np.ndarray:
    """Front projection: u from +x (left in the image) to -x, v from +y (top) down."""
    u0, v0, u1, v1 = r
    sx = (hi[0] - v[:, 0]) / max(hi[0] - lo[0], 1e-9)
    sy = (hi[1] - v[:, 1]) / max(hi[1] - lo[1], 1e-9)
    return np.column_stack([u0 + sx * (u1 - u0), v0 + sy * (v1 - v0)])


def _box(lo, hi) -> trimesh.Trimesh:
    return trimesh.creation.box(bounds=np.array([lo, hi], float))


def _fit(mesh: trimesh.Trimesh, lo, hi) -> trimesh.Trimesh:
    """Scale and move ``mesh`` so that its bounding box is exactly [lo, hi]."""
    m = mesh.copy()
    b0, b1 = m.bounds
    s = (np.asarray(hi, float) - lo) / (b1 - b0)
    m.apply_transform(np.diag([*s, 1.0]))
    m.apply_translation(np.asarray(lo, float) - m.bounds[0])
    return m


def _cylinder_z(cx, cy, r, z0, z1, sections=32) -> trimesh.Trimesh:
    """A cylinder along z (a wheel seen face-on)."""
    c = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=sections)
    return _fit(c, (cx - r, cy - r, z0), (cx + r, cy + r, z1))


def _cylinder_axis(axis: int, lo, hi, sections=32) -> trimesh.Trimesh:
    """A cylinder along ``axis`` (0 x, 1 y) fitted (squashed) into the box [lo, hi]."""
    c = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=sections)
    if axis == 0:
        c.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    elif axis == 1:
        c.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    return _fit(c, lo, hi)


def _rot_z(theta: float, pivot) -> np.ndarray:
    """4x4 rotation by theta (rad) about the z axis through ``pivot``."""
    return trimesh.transformations.rotation_matrix(theta, [0, 0, 1], point=pivot)


# --- Train set --------------------------------------------------------------------------------
@dataclass(frozen=True)
class TrainSpec:
    name: str
    z_front_mm: float
    rail_y_mm: float
    x_centre_mm: float
    units: tuple[str, ...]  # "loco" or "coach", from the unit at the +x end

    @property
    def length_mm(self) -> float:
        n = len(self.units)
        return n * UNIT_LEN_MM + (n - 1) * UNIT_GAP_MM


FAR_TRAIN = TrainSpec(
    "far_train", FAR_TRACK_Z_MM, FAR_RAIL_Y_MM, FAR_TRAIN_X_MM, ("coach", "coach", "loco")
)
NEAR_TRAIN = TrainSpec(
    "near_train", NEAR_TRACK_Z_MM, NEAR_RAIL_Y_MM, NEAR_TRAIN_X_MM, ("coach", "coach", "coach")
)

TRAIN_ATLAS = _Atlas(1856, 420)
PANEL_W, PANEL_H = 570, 168  # 95 x 28 mm at 6 texels/mm
CAB_W, CAB_H = 180, 204  # 30 x 34 mm
BOILER_W, BOILER_H = 372, 132  # 62 x 22 mm
T_PANEL = [(k * 600.0, 0.0, k * 600.0 + PANEL_W, PANEL_H) for k in range(3)]
T_CAB: Rect = (0, 200, CAB_W, 200 + CAB_H)
T_BOILER: Rect = (200, 200, 200 + BOILER_W, 200 + BOILER_H)
T_WHEEL: Rect = (600, 200, 728, 328)
T_DRIVER: Rect = (750, 200, 878, 328)
T_ROOF: Rect = (900, 200, 940, 240)
T_FRAME: Rect = (960, 200, 1000, 240)
T_RED: Rect = (1020, 200, 1060, 240)
T_STEEL: Rect = (1080, 200, 1120, 240)
T_BRASS: Rect = (1140, 200, 1180, 240)
T_BLACK: Rect = (1200, 200, 1240, 240)


def _wheel(b: _Builder, cx, cy, r, z0, tex: Rect = T_WHEEL) -> None:
    b.add(_cylinder_z(cx, cy, r, z0, z0 + 1.2), tex, T_STEEL)


def _coach(b: _Builder, x0: float, z: float, yr: float, panel: Rect) -> None:
    L = UNIT_LEN_MM
    b.add(_box((x0, yr + 10, z), (x0 + L, yr + 38, z + RELIEF_MM)), panel, T_ROOF)
    b.add(_box((x0 + 0.7, yr + 38, z + 0.3), (x0 + L - 0.7, yr + 42, z + 4.2)), T_ROOF)
    b.add(_box((x0 + 8, yr + 6.5, z + 0.8), (x0 + L - 8, yr + 10.2, z + 4.0)), T_FRAME)
    for xw in (12.0, 22.5, L - 22.5, L - 12.0):
        _wheel(b, x0 + xw, yr + 4.85, 4.8, z + 0.4)


def _loco(b: _Builder, x0: float, z: float, yr: float) -> None:
    L, cab = UNIT_LEN_MM, 30.0
    b.add(_box((x0 + L - cab, yr + 10, z), (x0 + L, yr + 44, z + RELIEF_MM)), T_CAB, T_ROOF)
    b.add(_box((x0 + L - cab - 1.5, yr + 44, z + 0.2), (x0 + L + 1.2, yr + 47, z + 4.3)), T_ROOF)
    b.add(
        _cylinder_axis(0, (x0 + 2.5, yr + 12.5, z + 0.1), (x0 + L - cab + 0.5, yr + 34.5, z + 4.4)),
        T_BOILER,
    )
    b.add(_cylinder_axis(1, (x0 + 9, yr + 31, z + 0.6), (x0 + 16, yr + 45, z + 3.9)), T_BLACK)
    b.add(_cylinder_axis(1, (x0 + 33, yr + 32, z + 0.8), (x0 + 41, yr + 38.5, z + 3.7)), T_BRASS)
    b.add(_box((x0 - 0.3, yr + 10.3, z + 0.2), (x0 + L - cab + 0.2, yr + 12.6, z + 4.4)), T_RED)
    b.add(_box((x0 - 2.5, yr + 8.5, z + 0.5), (x0 + 1.0, yr + 15.5, z + 4.0)), T_RED)
    b.add(_box((x0 + 6, yr + 5.5, z + 1.6), (x0 + L - 4, yr + 10.4, z + 4.0)), T_FRAME)
    _wheel(b, x0 + 11.0, yr + 4.85, 4.8, z + 0.4)
    for xw in (31.0, 48.0, 65.0):
        _wheel(b, x0 + xw, yr + 7.55, 7.5, z + 0.35, T_DRIVER)
    b.add(_box((x0 + 30, yr + 6.6, z + 0.05), (x0 + 66.5, yr + 8.1, z + 0.3)), T_STEEL)


def train_mesh(spec: TrainSpec) -> trimesh.Trimesh:
    """A train of units on the track at ``spec``: its camera-facing side at z = z_front_mm."""
    b = _Builder(TRAIN_ATLAS)
    x = spec.x_centre_mm + spec.length_mm / 2  # units from the +x end
    for k, unit in enumerate(spec.units):
        x0 = x - UNIT_LEN_MM
        if unit == "loco":
            _loco(b, x0, spec.z_front_mm, spec.rail_y_mm)
        else:
            _coach(b, x0, spec.z_front_mm, spec.rail_y_mm, T_PANEL[k])
        if k < len(spec.units) - 1:  # coupler into the next unit
            z, yr = spec.z_front_mm, spec.rail_y_mm
            lo = (x0 - UNIT_GAP_MM - 1.3, yr + 11.1, z + 1.5)
            b.add(_box(lo, (x0 + 1.1, yr + 13.9, z + 3.1)), T_BLACK)
        x = x0 - UNIT_GAP_MM
    return b.mesh()


TRACK_ATLAS = _Atlas(3120, 120)
T_BALLAST: Rect = (0, 0, 3120, 51)
T_SLEEPER: Rect = (0, 70, 40, 110)
T_RAIL: Rect = (60, 70, 100, 110)


def track_mesh(z: float, yr: float) -> trimesh.Trimesh:
    """Ballast strip, sleeper ends and two rails; rail tops at y = ``yr``, front at z."""
    b = _Builder(TRACK_ATLAS)
    h = TRACK_HALF_LEN_MM
    b.add(_box((-h, yr - 12.0, z), (h, yr - 3.5, z + RELIEF_MM)), T_BALLAST)
    for x in np.arange(-h + 2.7, h - 2.0, 6.0):
        b.add(_box((x, yr - 3.5, z + 0.3), (x + 2.2, yr - 1.5, z + 4.3)), T_SLEEPER)
    for z0 in (z + 0.5, z + 3.4):
        b.add(_box((-h + 0.4, yr - 1.5, z0), (h - 0.4, yr, z0 + 0.6)), T_RAIL)
    return b.mesh()


CAR_ATLAS = _Atlas(1024, 256)
T_CAR_BODY: Rect = (0, 0, 600, 96)
T_CAR_CABIN: Rect = (0, 120, 300, 192)
T_CAR_WHEEL: Rect = (640, 0, 768, 128)
T_CAR_RED: Rect = (800, 0, 840, 40)
T_CAR_DARK: Rect = (860, 0, 900, 40)


def car_mesh(z: float = CAR_Z_MM, x_centre: float = CAR_X_MM) -> trimesh.Trimesh:
    """A 1:43-like miniature car seen from its side: near wheels' faces at z."""
    b = _Builder(CAR_ATLAS)
    x0, y0 = x_centre - 50.0, CAR_GROUND_Y_MM
    b.add(_box((x0, y0 + 6, z + 1.0), (x0 + 100, y0 + 22, z + 12.0)), T_CAR_BODY, T_CAR_RED)
    b.add(_box((x0 + 25, y0 + 22, z + 2.0), (x0 + 75, y0 + 34, z + 11.0)), T_CAR_CABIN, T_CAR_RED)
    for xw in (18.0, 82.0):
        b.add(_cylinder_z(x0 + xw, y0 + 8.05, 8.0, z, z + 3.0), T_CAR_WHEEL, T_CAR_DARK)
    return b.mesh()


def plate_mesh(centre, size_mm, uv_repeat=(1.0, 1.0)) -> trimesh.Trimesh:
    """A one-sided rectangle facing the camera (-z normal), UVs 0..repeat (wrap repeats)."""
    (cx, cy, cz), (w, h) = centre, size_mm
    v = np.array(
        [
            [cx + w / 2, cy + h / 2, cz],
            [cx - w / 2, cy + h / 2, cz],
            [cx - w / 2, cy - h / 2, cz],
            [cx + w / 2, cy - h / 2, cz],
        ]
    )
    ru, rv = uv_repeat
    uv = np.array([[0, 0], [ru, 0], [ru, rv], [0, rv]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    m = trimesh.Trimesh(v, f, visual=trimesh.visual.TextureVisuals(uv=uv), process=False)
    if m.face_normals[0, 2] > 0:
        m.invert()
    return m


def floor_mesh(y, x_half, z0, z1, tile_mm) -> trimesh.Trimesh:
    """A horizontal floor (+y normal) from depth z0 to z1, tiled every ``tile_mm``."""
    v = np.array([[x_half, y, z0], [-x_half, y, z0], [-x_half, y, z1], [x_half, y, z1]])
    uv = np.array([[0, 0], [2 * x_half, 0], [2 * x_half, z1 - z0], [0, z1 - z0]]) / tile_mm
    m = trimesh.Trimesh(
        v, [[0, 1, 2], [0, 2, 3]], process=False, visual=trimesh.visual.TextureVisuals(uv=uv)
    )
    if m.face_normals[0, 1] < 0:
        m.invert()
    return m


# --- Soccer ball ------------------------------------------------------------------------------
def ball_mesh(centre=BALL_CENTRE_MM, radius=BALL_RADIUS_MM, n_theta=48) -> trimesh.Trimesh:
    """A latitude-longitude sphere; u = phi / 2 pi, v = theta / pi (see ``ball_direction``)."""
    n_phi = 2 * n_theta
    th = np.linspace(0, math.pi, n_theta + 1)
    ph = np.linspace(0, 2 * math.pi, n_phi + 1)
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = _sphere_dir(T, P).reshape(-1, 3)
    uv = np.column_stack([(P / (2 * math.pi)).ravel(), (T / math.pi).ravel()])
    idx = np.arange((n_theta + 1) * (n_phi + 1)).reshape(n_theta + 1, n_phi + 1)
    a, b, c, e = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    down = np.stack([a, c, e], -1)[:-1]  # the last ring's would be degenerate at the pole
    up = np.stack([a, e, b], -1)[1:]  # likewise the first ring's
    f = np.concatenate([down.reshape(-1, 3), up.reshape(-1, 3)])
    m = trimesh.Trimesh(
        np.asarray(centre) + radius * d,
        f,
        process=False,
        visual=trimesh.visual.TextureVisuals(uv=uv),
    )
    if m.volume < 0:
        m.invert()
    return m


def _sphere_dir(theta, phi) -> np.ndarray:
    """Unit direction for polar angle theta (from +y) and azimuth phi."""
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), np.cos(theta), s * np.sin(phi)], -1)


def _truncated_icosahedron_planes() -> tuple[np.ndarray, np.ndarray]:
    """Unit normals and plane distances of a football's 12 pentagons and 20 hexagons."""
    ico = trimesh.creation.icosahedron()
    V = ico.vertices
    nbr = {
        i: sorted({int(j) for e in ico.edges_unique for j in e if i in e} - {i})
        for i in range(len(V))
    }
    normals, dists = [], []
    for i in range(len(V)):  # pentagon at each icosahedron vertex
        n = V[i] / np.linalg.norm(V[i])
        normals.append(n)
        dists.append(n @ (V[i] + (V[nbr[i][0]] - V[i]) / 3))
    for a, b, _ in ico.faces:  # hexagon at each icosahedron face
        n = ico.vertices[[a, b, _]].mean(0)
        n /= np.linalg.norm(n)
        normals.append(n)
        dists.append(n @ (V[a] + (V[b] - V[a]) / 3))
    return np.array(normals), np.array(dists)


# --- Walker -----------------------------------------------------------------------------------
WALKER_ATLAS = _Atlas(1024, 1024)
T_SHIRT: Rect = (0, 0, 512, 512)
T_TROUSERS: Rect = (512, 0, 1024, 512)
T_HEAD: Rect = (0, 512, 256, 768)
T_SKIN: Rect = (300, 540, 340, 580)
T_SHOE: Rect = (360, 540, 400, 580)
T_SLEEVE: Rect = (0, 512 + 300, 256, 1024)


def walker_pivots() -> dict[str, tuple[float, float, float]]:
    """Hip and shoulder joints (mm) of the four limbs at t = 0."""
    z = WALKER_Z_MM
    return {
        "walker_leg_near": (0.0, HIP_Y_MM, z - LEG_Z_OFFSET_MM),
        "walker_leg_far": (0.0, HIP_Y_MM, z + LEG_Z_OFFSET_MM),
        "walker_arm_near": (0.0, SHOULDER_Y_MM, z - ARM_Z_OFFSET_MM),
        "walker_arm_far": (0.0, SHOULDER_Y_MM, z + ARM_Z_OFFSET_MM),
    }


def limb_angle_rad(name: str, t_ms) -> np.ndarray:
    """Swing angle of a limb (rad, about +z: positive swings it towards +x, forwards)."""
    amp = LEG_SWING_DEG if "leg" in name else ARM_SWING_DEG
    sign = 1.0 if name in ("walker_leg_near", "walker_arm_far") else -1.0  # arms oppose legs
    w = 2 * math.pi / GAIT_PERIOD_MS
    return sign * np.radians(amp) * np.sin(w * np.asarray(t_ms, float) + np.radians(GAIT_PHASE_DEG))


def walker_meshes() -> dict[str, trimesh.Trimesh]:
    """A simply articulated person in profile, walking towards +x: a rigid body (torso, neck,
    head) and four limbs posed at their t = 0 angles."""
    z = WALKER_Z_MM
    body = _Builder(WALKER_ATLAS)
    caps = trimesh.creation.capsule(height=2.0, radius=1.0, count=[24, 24])
    caps.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    body.add(_fit(caps, (-120, -40, z - 190), (120, 500, z + 190)), T_SHIRT)
    body.add(_cylinder_axis(1, (-45, 470, z - 50), (55, 560, z + 50)), T_SKIN)
    head = trimesh.creation.icosphere(subdivisions=3)
    body.add(_fit(head, (-95, 530, z - 95), (105, 770, z + 95)), T_HEAD)
    out = {"walker_body": body.mesh()}
    for name, pivot in walker_pivots().items():
        limb = _Builder(WALKER_ATLAS)
        zc = pivot[2]
        if "leg" in name:
            limb.add(
                _fit(caps, (-75, WALKER_FLOOR_Y_MM + 20, zc - 75), (75, 60, zc + 75)), T_TROUSERS
            )
            foot = (-45, WALKER_FLOOR_Y_MM, zc - 50), (135, WALKER_FLOOR_Y_MM + 55, zc + 50)
            limb.add(_box(*foot), T_SHOE)
        else:
            limb.add(_fit(caps, (-45, -210, zc - 45), (45, 475, zc + 45)), T_SLEEVE, T_SKIN)
        m = limb.mesh()
        m.apply_transform(_rot_z(float(limb_angle_rad(name, 0.0)), pivot))
        out[name] = m
    return out


def meshes() -> dict[str, trimesh.Trimesh]:
    """Every mesh of the built-in scenes, by file stem (world mm, pose at t = 0)."""
    bw, bh = BACKDROP_SIZE_MM
    out = {
        "far_train": train_mesh(FAR_TRAIN),
        "near_train": train_mesh(NEAR_TRAIN),
        "far_track": track_mesh(FAR_TRACK_Z_MM, FAR_RAIL_Y_MM),
        "near_track": track_mesh(NEAR_TRACK_Z_MM, NEAR_RAIL_Y_MM),
        "car": car_mesh(),
        "backdrop": plate_mesh((0.0, 0.0, BACKDROP_Z_MM), (bw, bh)),
        "soccer_ball": ball_mesh(),
        "soccer_wall": plate_mesh((0, 0, SOCCER_WALL_Z_MM), (1800, 1400), (6.0, 1400 / 300)),
        "walker_wall": plate_mesh((0, 400, WALKER_WALL_Z_MM), (4400, 4200), (4400 / 600, 7.0)),
        "walker_floor": floor_mesh(WALKER_FLOOR_Y_MM, 2600.0, 1400.0, WALKER_WALL_Z_MM, 500.0),
    }
    out.update(walker_meshes())
    return out


CLOSED_MESHES = (
    "far_train",
    "near_train",
    "far_track",
    "near_track",
    "car",
    "soccer_ball",
    "walker_body",
    "walker_leg_near",
    "walker_leg_far",
    "walker_arm_near",
    "walker_arm_far",
)
"""Meshes that must be closed (watertight once coincident corners are merged)."""


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
    n, d = _truncated_icosahedron_planes()
    h = w // 2
    v, u = (np.mgrid[0:h, 0:w] + 0.5) / np.array([h, w])[:, None, None]
    dirs = _sphere_dir(math.pi * v, 2 * math.pi * u)
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
