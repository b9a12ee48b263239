"""Deterministic meshes of the built-in scenes (trimesh + numpy), and their UV atlases.

Everything is in millimetres, in world coordinates, in the pose at t = 0 (:mod:`.layout`).
Meshes carry per-face UVs into one texture atlas per object (the ``*_ATLAS`` sizes and ``T_*``
texel rectangles, which :mod:`.textures` paints). UV convention (checked with a render): u, v
are PNG column / row fractions, v = 0 at the top row; a front face maps u = 0 to its largest x
so that textures read unmirrored in the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..lazy import lazy_module
from .layout import (
    BACKDROP_SIZE_MM,
    BACKDROP_Z_MM,
    BALL_CENTRE_MM,
    BALL_RADIUS_MM,
    CAR_GROUND_Y_MM,
    CAR_X_MM,
    CAR_Z_MM,
    FAR_RAIL_Y_MM,
    FAR_TRACK_Z_MM,
    FAR_TRAIN_X_MM,
    NEAR_RAIL_Y_MM,
    NEAR_TRACK_Z_MM,
    NEAR_TRAIN_X_MM,
    RELIEF_MM,
    SOCCER_WALL_Z_MM,
    TRACK_HALF_LEN_MM,
    UNIT_GAP_MM,
    UNIT_LEN_MM,
    WALKER_FLOOR_Y_MM,
    WALKER_WALL_Z_MM,
    WALKER_Z_MM,
    limb_angle_rad,
    walker_pivots,
)

Rect = tuple[float, float, float, float]  # texel rectangle (col0, row0, col1, row1)

trimesh = lazy_module("trimesh")  # 1.2 s to import: loaded when a mesh is built


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
    d = sphere_dir(T, P).reshape(-1, 3)
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


def sphere_dir(theta, phi) -> np.ndarray:
    """Unit direction for polar angle theta (from +y) and azimuth phi."""
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), np.cos(theta), s * np.sin(phi)], -1)


def truncated_icosahedron_planes() -> tuple[np.ndarray, np.ndarray]:
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
