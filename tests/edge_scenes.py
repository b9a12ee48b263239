"""Edge scenes for the MTF checks (``tests/exposure``, ``tests/render``): a straight, tilted
edge of a radiance-1 emitter at one depth, rendered through a capture."""

from __future__ import annotations

import warnings

import numpy as np

from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.scenes.description import SceneDescription

BIG_MM = 400.0
"""Half the side of each half-plane, mm: far beyond any window's field."""


def _half(turn: np.ndarray, side: float) -> np.ndarray:
    """Local [-1, 1]^2 -> x' in [0, 2 BIG] (side +1) or [-2 BIG, 0] (side -1), the front
    (+z) turned to -z (the camera), then tilted and placed by ``turn``."""
    local = np.array([[BIG_MM, 0, 0, side * BIG_MM], [0, BIG_MM, 0, 0], [0, 0, -1.0, 0],
                      [0, 0, 0, 1.0]])  # fmt: skip
    return turn @ local


def edge_scene(z_mm: float, tilt_deg: float, dark_half: bool = False) -> SceneDescription:
    """A half-plane emitter of radiance 1 at depth z, its edge through the axis, tilted; with
    ``dark_half`` a black diffuse half-plane at the same depth fills the other side (a camera
    ray then meets a surface at z on both sides, as on one object's painted edge)."""
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    turn = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1.0, z_mm], [0, 0, 0, 1.0]])
    light = {"type": "area", "radiance": {"type": "rgb", "value": [1.0] * 3}}
    shapes = {"edge": {"type": "rectangle", "to_world": _half(turn, -1.0), "emitter": light}}
    if dark_half:
        black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}
        shapes["dark"] = {"type": "rectangle", "to_world": _half(turn, 1.0), "bsdf": black}
    return SceneDescription("edge", {"type": "scene", **shapes}, {})


def render_edge(spec_kw: dict, desc: SceneDescription, **kw):
    """``render_capture`` of the edge, quietly, without truth layers."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return render_capture(
            CaptureSpec.geometric(**spec_kw, **kw), progress=False, description=desc, truth=False
        )
