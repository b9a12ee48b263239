"""Seeded drawing of a family scene's objects (:func:`draw_objects`): shape, depth, size,
place and image velocity of each, with ``numpy.random.default_rng`` only.

A draw that fails its family's conditions (two objects that would pass through each other;
for ``occluders``, no guaranteed occlusion) is redrawn with a derived seed, ``[seed, attempt]``,
up to :data:`MAX_ATTEMPTS` times: the same seed and parameters always end on the same attempt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import ParameterError
from ...model.camera import CameraDesign
from ..motion import image_to_scene_velocity
from .occlusion import Footprint, occlusion_events
from .spec import DEPTH_SAMPLING

SHAPES = ("rectangle", "box", "sphere", "cylinder")
"""The object shapes, all Mitsuba's own plugins: a textured card facing the camera, a cube
(scaled), a sphere and a vertical open cylinder (Mitsuba's ``cylinder`` has no end caps)."""
MAX_ATTEMPTS = 200
"""Draws tried before a family's conditions are declared unreachable for the parameters."""
MAX_PLACEMENTS = 50
"""Places tried for one object before the draw is abandoned."""
DEPTH_GAP_MM = 1.0
"""The least depth gap between two objects whose paths cross (else they would interpenetrate)."""


@dataclass(frozen=True)
class FamilyObject:
    """One drawn object. Lengths mm, image quantities px at the camera's scale, times ms.

    ``centre_mm`` is its centre at t = 0 (``depth_mm`` its z); ``size_mm`` its width, height
    and depth; ``size_px`` its width and height at ``depth_mm``; ``image_velocity_px_per_ms``
    (du, dv) with u to the image's right and v down; ``image_speed_px_per_ms`` its signed speed
    along ``direction_deg`` (the angle from the image's horizontal, positive downwards).
    """

    object_id: str
    shape: str
    centre_mm: tuple[float, float, float]
    size_mm: tuple[float, float, float]
    size_px: tuple[float, float]
    centre_px: tuple[float, float]
    image_speed_px_per_ms: float
    direction_deg: float
    image_velocity_px_per_ms: tuple[float, float]
    velocity_mm_per_ms: tuple[float, float, float]

    @property
    def depth_mm(self) -> float:
        return self.centre_mm[2]

    def footprint(self) -> Footprint:
        """The image footprint that the occlusion test uses (:mod:`.occlusion`)."""
        kind = "disc" if self.shape == "sphere" else "rect"
        half = (0.5 * self.size_px[0], 0.5 * self.size_px[1])
        return Footprint(
            self.object_id, self.depth_mm, kind, self.centre_px, half, self.image_velocity_px_per_ms
        )

    def swept_box_mm(self, T_ms: float) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned box holding the object over [-T, T]."""
        c, s = np.asarray(self.centre_mm), 0.5 * np.asarray(self.size_mm)
        reach = np.abs(self.velocity_mm_per_ms) * T_ms
        return c - s - reach, c + s + reach


def _depth_mm(rng, family: str, lo: float, hi: float) -> float:
    if DEPTH_SAMPLING[family] == "inverse":
        return float(1.0 / rng.uniform(1.0 / hi, 1.0 / lo))
    return float(rng.uniform(lo, hi))


def _one_object(rng, k: int, family: str, p: dict, cam: CameraDesign) -> FamilyObject:
    """Draw object ``k``: shape, depth, size, place (its centre inside the window at t = 0)
    and image velocity."""
    f_px, W, H = cam.focal_length_px, cam.width_px, cam.height_px
    shape = SHAPES[int(rng.integers(len(SHAPES)))]
    z = _depth_mm(rng, family, *p["depth_range_mm"])
    w_px = float(rng.uniform(*p["size_range_px"]))
    h_px = w_px if shape == "sphere" else float(rng.uniform(*p["size_range_px"]))
    x, y, w, h = p["window"]
    u0, v0 = float(rng.uniform(x, x + w)), float(rng.uniform(y, y + h))
    lo, hi = p["speed_range_px_per_ms"]
    speed = float(rng.uniform(lo, hi)) * (1.0 if rng.integers(2) else -1.0)
    spread = p["direction_spread_deg"]
    angle = float(rng.uniform(-spread, spread)) if spread > 0 else 0.0
    duv = (speed * math.cos(math.radians(angle)), speed * math.sin(math.radians(angle)))
    mm_per_px = z / f_px
    w_mm, h_mm = w_px * mm_per_px, h_px * mm_per_px
    d_mm = {"rectangle": 0.0, "box": min(w_mm, h_mm), "sphere": w_mm, "cylinder": w_mm}[shape]
    v_mm = image_to_scene_velocity(duv, z, cam)
    return FamilyObject(
        object_id=f"object_{k}",
        shape=shape,
        centre_mm=((0.5 * W - u0) * mm_per_px, (0.5 * H - v0) * mm_per_px, z),
        size_mm=(w_mm, h_mm, d_mm),
        size_px=(w_px, h_px),
        centre_px=(u0, v0),
        image_speed_px_per_ms=speed,
        direction_deg=angle,
        image_velocity_px_per_ms=duv,
        velocity_mm_per_ms=tuple(float(c) for c in v_mm),
    )


def _collides(a: FamilyObject, b: FamilyObject, T_ms: float) -> bool:
    """Whether ``a`` and ``b`` could touch during the exposure (their swept boxes, widened by
    half of :data:`DEPTH_GAP_MM` in depth, intersect)."""
    (alo, ahi), (blo, bhi) = a.swept_box_mm(T_ms), b.swept_box_mm(T_ms)
    gap = np.array([0.0, 0.0, 0.5 * DEPTH_GAP_MM])
    return bool(np.all(alo - gap < bhi + gap) and np.all(blo - gap < ahi + gap))


def _attempt(rng, family: str, p: dict, cam: CameraDesign) -> list[FamilyObject] | None:
    """One draw of the objects, or None if one finds no place clear of the others."""
    n = int(rng.integers(p["object_count"][0], p["object_count"][1] + 1))
    objects: list[FamilyObject] = []
    for k in range(n):
        for _ in range(MAX_PLACEMENTS):
            obj = _one_object(rng, k, family, p, cam)
            if not any(_collides(obj, o, cam.T_ms) for o in objects):
                objects.append(obj)
                break
        else:
            return None
    return objects


def draw_objects(
    family: str, seed: int, p: dict, cam: CameraDesign
) -> tuple[list[FamilyObject], list[dict], int]:
    """The objects of scene ``seed``, its occlusion events and the attempt that was kept.

    Parameters
    ----------
    family : str
    seed : int
    p : dict
        Checked parameters (:func:`~.spec.resolve_params`).
    cam : CameraDesign
        The camera whose scale ``p`` is in.

    Returns
    -------
    tuple
        (objects, events, attempt).

    Raises
    ------
    ParameterError
        If :data:`MAX_ATTEMPTS` draws all fail the family's conditions.
    """
    for attempt in range(MAX_ATTEMPTS):
        rng = np.random.default_rng([seed, attempt, 0])
        objects = _attempt(rng, family, p, cam)
        if objects is None:
            continue
        events = occlusion_events([o.footprint() for o in objects], p["window"], cam.T_ms)
        if family != "occluders" or any(e["passes"] for e in events):
            return objects, events, attempt
    need = "objects clear of each other" + (" and an occlusion" if family == "occluders" else "")
    raise ParameterError(
        f"no draw of family {family!r} with seed {seed} gave {need} in {MAX_ATTEMPTS} attempts; "
        "widen depth_range_mm, or lower object_count or size_range_px"
    )
