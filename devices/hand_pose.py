"""Hand joints: the official 21-joint order and the official validity rule for a hand's pose."""
from __future__ import annotations

import numpy as np

JOINTS_PER_HAND = 21
MAX_ABS_XY = 1000.0
MAX_Z = 1000.0


def hand_from_json(value: object) -> tuple[np.ndarray, bool]:
    """Parse one hand's `*_pos` field into ((21, 3) float32, valid).

    Official rule: valid when the list has exactly 21 rows of 3 numbers, no NaN/inf, max |x|,|y| ≤ 1000
    and max z ≤ 1000. An invalid hand is returned as zeros.
    """
    zeros = np.zeros((JOINTS_PER_HAND, 3), np.float32)
    if not isinstance(value, list) or len(value) != JOINTS_PER_HAND:
        return zeros, False
    try:
        xyz = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return zeros, False
    if xyz.shape != (JOINTS_PER_HAND, 3) or not pose_is_valid(xyz):
        return zeros, False
    return xyz.astype(np.float32), True


def pose_is_valid(xyz: np.ndarray) -> bool:
    """The official bounds check for one hand's (21, 3) joints."""
    if not np.all(np.isfinite(xyz)):
        return False
    return bool(np.abs(xyz[:, :2]).max() <= MAX_ABS_XY and xyz[:, 2].max() <= MAX_Z)


def hands_valid(joints: np.ndarray) -> np.ndarray:
    """Apply the validity rule to (..., 2, 21, 3) joints; returns (..., 2) bool."""
    flat = joints.reshape(-1, JOINTS_PER_HAND, 3)
    valid = np.array([pose_is_valid(h) for h in flat], dtype=bool)
    return valid.reshape(joints.shape[:-2])
