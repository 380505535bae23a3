"""Hand joints: the official 21-joint order, the official validity rule for a hand's pose, and WiLoR's camera.

WiLoR's camera (the frame the model's joints live in): focal length 5000/256 · max(W, H) pixels, principal
point at the image centre, axes x right, y down, z forward; joints in metres, depth stretched by that long
focal length (the hand projects to the same pixels as through the real camera).
"""
from __future__ import annotations

import numpy as np

JOINTS_PER_HAND = 21
JOINT_NAMES = ("wrist",) + tuple(f"{finger}_{k}" for finger in ("thumb", "index", "middle", "ring", "pinky") for k in range(1, 5))
"""The 21 joints in the official order: wrist, then thumb, index, middle, ring and pinky from base (1) to tip (4)."""
MAX_ABS_XY = 1000.0
MAX_Z = 1000.0
WILOR_FOCAL_PER_PIXEL = 5000.0 / 256.0


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


def wilor_focal_px(width: int, height: int) -> float:
    """WiLoR's focal length in pixels for a W×H image: 5000/256 · max(W, H)."""
    return WILOR_FOCAL_PER_PIXEL * max(width, height)


def project_wilor(joints: np.ndarray, width: int, height: int) -> np.ndarray:
    """(..., 3) joints in WiLoR's camera frame → (..., 2) pixel coordinates in a W×H image; NaN where
    z ≤ 0 or not finite."""
    joints = np.asarray(joints, np.float64)
    focal = wilor_focal_px(width, height)
    z = joints[..., 2]
    ok = np.isfinite(joints).all(axis=-1) & (z > 1e-6)
    safe = np.where(ok, z, 1.0)
    uv = np.stack([focal * joints[..., 0] / safe + width / 2, focal * joints[..., 1] / safe + height / 2], axis=-1)
    return np.where(ok[..., None], uv, np.nan)
