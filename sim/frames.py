"""Frame conventions between MuJoCo (body x forward, y left, z up; world z up) and the flight software
(aerospace angles: positive roll = right side down, positive pitch = nose up, positive yaw = nose right;
body rates p, q, r about forward, right and down axes), all in degrees.
"""

from __future__ import annotations

import math

import numpy as np

RAD2DEG = 180.0 / math.pi

# FRD rate = FLU_TO_FRD * FLU rate (x kept, y and z flipped)
FLU_TO_FRD = np.array([1.0, -1.0, -1.0])
# MuJoCo world (x north, z up) vector = NED_TO_ZUP * NED vector (north kept, east and down flipped)
NED_TO_ZUP = np.array([1.0, -1.0, -1.0])
AXES = ("roll", "pitch", "yaw")


def euler_deg(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """Aerospace (roll, pitch, yaw) in degrees of a body (FLU) orientation in the z-up world, from its unit
    quaternion's components (plain floats: math on numpy scalars costs several times more, and this runs twice
    per tick)."""
    # rows of the rotation matrix that the angles need (float literals: CPython's float-only operations are the
    # cheaper ones, and 2.0 * x is 2 * x exactly)
    r00 = 1.0 - 2.0 * (y * y + z * z)
    r10 = 2.0 * (x * y + w * z)
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    # max(-1.0, min(1.0, r20)) as comparisons, the builtins' very results (a NaN gives 1.0) without two calls
    r20 = r20 if r20 < 1.0 else 1.0
    pitch = math.asin(r20 if r20 > -1.0 else -1.0)  # forward axis rising = nose up
    roll = math.atan2(r21, r22)  # left axis rising = right side down
    yaw = -math.atan2(r10, r00)  # heading turning clockwise seen from above = nose right
    return roll * RAD2DEG, pitch * RAD2DEG, yaw * RAD2DEG


def euler_deg_from_quat(quat_wxyz) -> np.ndarray:
    """:func:`euler_deg` of a quaternion ``(w, x, y, z)`` (array or sequence), as an array ``(3,)``."""
    return np.array(euler_deg(*(quat_wxyz.tolist() if hasattr(quat_wxyz, "tolist") else quat_wxyz)))


def euler_deg_from_quats(quat_wxyz) -> np.ndarray:
    """Aerospace (roll, pitch, yaw) in degrees of body (FLU) orientations in the z-up world, ``(n, 4) -> (n, 3)``
    (:func:`euler_deg_from_quat` over rows)."""
    q = np.asarray(quat_wxyz, dtype=float)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r00 = 1 - 2 * (y * y + z * z)
    r10 = 2 * (x * y + w * z)
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    out = np.empty((q.shape[0], 3))
    out[:, 0] = np.arctan2(r21, r22) * RAD2DEG
    out[:, 1] = np.arcsin(np.clip(r20, -1.0, 1.0)) * RAD2DEG
    out[:, 2] = -np.arctan2(r10, r00) * RAD2DEG
    return out


def rates_dps_from_flu(omega_flu_rad_s) -> np.ndarray:
    """Body rates (p, q, r) in deg/s from a FLU angular velocity in rad/s."""
    return FLU_TO_FRD * np.asarray(omega_flu_rad_s) * RAD2DEG
