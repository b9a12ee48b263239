"""Where the built-in scenes' objects stand, and how the walker's limbs swing.

World millimetres, in the pose at t = 0 (mid-exposure): the camera sits at the origin looking
down +z (+y up; world +x shows on the image's *left*), so an object at depth Z has z = Z. The
meshes (:mod:`.meshes`) are built at these places and :mod:`.builtin` moves them from here.
"""

from __future__ import annotations

import math

import numpy as np

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
