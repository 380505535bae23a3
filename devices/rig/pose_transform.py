"""Hand pose for the model: mocap joints → the head-camera frame in the WiLoR convention.

Frames (all right-handed unless said):
- mocap: Rokoko Studio coordinates, Y up, Z forward, metres (left-handed, as Studio sends them).
- tracking universe: where the Vive trackers' poses live (OpenVR's standing universe: Y up, metres).
- chest tracker: the tracker's own axes; the head camera is rigidly mounted with it (the EgoTouch rig's
  head/chest camera rides on the chest with the chest tracker).
- head camera: OpenCV axes, x right, y down, z forward, metres.
- WiLoR convention (what the model was trained on): the head-camera frame, but as WiLoR reports it for a
  camera of focal length 5000/256 · max(W, H) px with the principal point at the image centre: the hand's
  shape (joints relative to the wrist) stays metric, and the wrist keeps x, y (metres) while its depth z is
  scaled by WiLoR's focal / the real focal, so the wrist projects to the same pixel through either camera.

Chain: joints_tracking = tracking_from_mocap · joints_mocap; joints_camera = (tracking_from_chest ·
chest_from_camera)⁻¹ · joints_tracking; then the WiLoR depth scaling of the wrist.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from touchanything.core.errors import UserError
from touchanything.core.hand_pose import JOINTS_PER_HAND, pose_is_valid, wilor_focal_px

ORTHONORMAL_TOLERANCE = 1e-3
"""How far tracking_from_mocap's 3×3 part may be from orthonormal (typed-in cosines have ~1e-4 error)."""
CALIBRATION_KEYS = ("tracking_from_mocap", "camera_in_chest_trans", "camera_in_chest_wxyz", "image_size", "focal_px")

NO_CHEST = "no chest tracker pose"
BAD_CHEST = "chest tracker pose is not finite or has a zero quaternion"
NOT_TRACKED = "hand not tracked by the mocap"
NOT_FINITE = "mocap joints are not finite"
OUT_OF_BOUNDS = "outside the official pose bounds"


def wilor_from_camera(joints: np.ndarray, depth_scale: float) -> np.ndarray:
    """(..., 21, 3) metric head-camera joints → the WiLoR convention: the wrist's (joint 0) z times
    `depth_scale` (= WiLoR focal / real focal), the hand's shape relative to the wrist unchanged."""
    root = joints[..., :1, :]
    return (joints - root) + root * np.array([1.0, 1.0, depth_scale])


@dataclass(frozen=True)
class PoseCalibration:
    """What a scene file's `[pose]` section carries (keys 1:1, plain numbers).

    tracking_from_mocap: 3×4 rows [A | t] mapping mocap (Studio) coordinates to the tracking universe,
        metres; A is orthonormal with det ±1 (−1 when it also converts Studio's left-handed axes).
    camera_in_chest_trans: (3,) the head camera's origin in the chest tracker's frame, metres.
    camera_in_chest_wxyz: (4,) the head camera's orientation in the chest tracker's frame (w, x, y, z);
        normalised on use.
    image_size: (W, H) of the head camera image, pixels.
    focal_px: the head camera's focal length, pixels (principal point assumed at the image centre).
    """

    tracking_from_mocap: tuple[tuple[float, ...], ...]
    camera_in_chest_trans: tuple[float, ...]
    camera_in_chest_wxyz: tuple[float, ...]
    image_size: tuple[int, int]
    focal_px: float

    def __post_init__(self) -> None:
        matrix = _array("tracking_from_mocap", self.tracking_from_mocap, (3, 4),
                        "a 3×4 matrix of finite numbers (rows [A | t])")
        deviation = np.abs(matrix[:, :3] @ matrix[:, :3].T - np.eye(3)).max()
        if deviation > ORTHONORMAL_TOLERANCE:
            raise UserError(f"[pose] tracking_from_mocap: its 3×3 part is not a rotation or reflection "
                            f"(A·Aᵀ differs from I by {deviation:.3g}); use orthonormal rows")
        _array("camera_in_chest_trans", self.camera_in_chest_trans, (3,), "3 finite numbers (x, y, z metres)")
        quat = _array("camera_in_chest_wxyz", self.camera_in_chest_wxyz, (4,), "4 finite numbers (w, x, y, z)")
        if np.linalg.norm(quat) < 1e-6:
            raise UserError("[pose] camera_in_chest_wxyz is zero; give a unit quaternion (w, x, y, z)")
        size = self.image_size
        if not (isinstance(size, tuple) and len(size) == 2 and all(_whole(v) and v > 0 for v in size)):
            raise UserError(f"[pose] image_size must be two positive whole numbers [width, height], got {size}")
        if not (math.isfinite(self.focal_px) and self.focal_px > 0):
            raise UserError(f"[pose] focal_px must be a positive number of pixels, got {self.focal_px}")

    @property
    def depth_scale(self) -> float:
        """WiLoR's focal length over the head camera's: how much the wrist's depth is stretched."""
        return wilor_focal_px(*self.image_size) / self.focal_px

    @classmethod
    def from_dict(cls, section: Mapping[str, object]) -> PoseCalibration:
        """From a scene TOML `[pose]` table (or the same dict); UserError naming the bad key."""
        if not isinstance(section, Mapping):
            raise UserError(f"[pose] must be a table of calibration keys, got {section!r}")
        unknown = sorted(set(section) - set(CALIBRATION_KEYS))
        if unknown:
            raise UserError(f"[pose] unknown key {unknown[0]!r}; the keys are {', '.join(CALIBRATION_KEYS)}")
        missing = [key for key in CALIBRATION_KEYS if key not in section]
        if missing:
            raise UserError(f"[pose] missing key {missing[0]!r}; the keys are {', '.join(CALIBRATION_KEYS)}")
        size = section["image_size"]
        return cls(
            tracking_from_mocap=_numbers("tracking_from_mocap", section["tracking_from_mocap"], 2),
            camera_in_chest_trans=_numbers("camera_in_chest_trans", section["camera_in_chest_trans"], 1),
            camera_in_chest_wxyz=_numbers("camera_in_chest_wxyz", section["camera_in_chest_wxyz"], 1),
            image_size=tuple(size) if isinstance(size, (list, tuple)) else size,
            focal_px=_numbers("focal_px", section["focal_px"], 0),
        )

    def to_dict(self) -> dict[str, object]:
        """Plain lists and numbers, the `[pose]` table that from_dict reads back."""
        return {
            "tracking_from_mocap": [list(row) for row in self.tracking_from_mocap],
            "camera_in_chest_trans": list(self.camera_in_chest_trans),
            "camera_in_chest_wxyz": list(self.camera_in_chest_wxyz),
            "image_size": list(self.image_size),
            "focal_px": self.focal_px,
        }


def _array(key: str, value: object, shape: tuple[int, ...], expected: str) -> np.ndarray:
    """`value` as a float64 array of `shape` with finite entries, else UserError naming `key`."""
    try:
        array = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        array = np.empty(0)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise UserError(f"[pose] {key} must be {expected}")
    return array


def _whole(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _numbers(key: str, value: object, depth: int) -> float | tuple:
    """`value` as floats in tuples nested `depth` deep (0 = one number); UserError unless every leaf is a
    real number (bool and text are refused). Shapes are checked by PoseCalibration itself."""
    if depth == 0:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise UserError(f"[pose] {key} must hold numbers, got {value!r}")
        return float(value)
    if not isinstance(value, (list, tuple)):
        raise UserError(f"[pose] {key} must be a list of numbers, got {value!r}")
    return tuple(_numbers(key, item, depth - 1) for item in value)


@dataclass(frozen=True)
class ModelFrameHands:
    """joints: (2, 21, 3) float32 left, right in the WiLoR convention (zeros for an invalid hand);
    valid: (2,) bool; reasons: per hand, "" when valid, else why not (for the dashboard)."""

    joints: np.ndarray
    valid: np.ndarray
    reasons: tuple[str, str]


def mocap_to_model_frame(joints: np.ndarray, present: np.ndarray, trackers: Mapping[str, np.ndarray],
                         calibration: PoseCalibration) -> ModelFrameHands:
    """Mocap hands (2, 21, 3) in Studio coordinates (metres) with present (2,) bool, and tracker poses
    {role: (7,) x, y, z, qw, qx, qy, qz} in the tracking universe → the model's hand input.

    The head camera's pose is the chest tracker's pose times the fixed camera_in_chest calibration; without
    a usable chest pose both hands are invalid. A hand with any NaN/inf joint is invalid. The result must
    pass the official validity rule (finite, |x|, |y| ≤ 1000, z ≤ 1000); a hand behind the camera (z ≤ 0)
    is kept, since that rule allows it.
    """
    joints = np.asarray(joints, np.float64).reshape(2, JOINTS_PER_HAND, 3)
    camera_pose = _camera_pose(trackers.get("chest"), calibration)
    if isinstance(camera_pose, str):
        return _result(np.zeros((2, JOINTS_PER_HAND, 3)), (camera_pose, camera_pose))
    rotation, origin = camera_pose
    matrix = np.asarray(calibration.tracking_from_mocap, float)
    with np.errstate(over="ignore", invalid="ignore"):
        tracking = joints @ matrix[:, :3].T + matrix[:, 3]
        camera = rotation.apply(tracking.reshape(-1, 3) - origin, inverse=True).reshape(tracking.shape)
        model = wilor_from_camera(camera, calibration.depth_scale)
    reasons = tuple(_reason(bool(present[h]), joints[h], model[h]) for h in range(2))
    return _result(model, reasons)


def _camera_pose(chest: np.ndarray | None,
                 calibration: PoseCalibration) -> tuple[Rotation, np.ndarray] | str:
    """The head camera's (rotation, origin) in the tracking universe, or why there is none."""
    if chest is None:
        return NO_CHEST
    chest = np.asarray(chest, np.float64)
    if chest.shape != (7,) or not np.all(np.isfinite(chest)) or np.linalg.norm(chest[3:]) < 1e-6:
        return BAD_CHEST
    chest_rotation = Rotation.from_quat(chest[3:], scalar_first=True)
    mount = Rotation.from_quat(calibration.camera_in_chest_wxyz, scalar_first=True)
    return chest_rotation * mount, chest[:3] + chest_rotation.apply(calibration.camera_in_chest_trans)


def _reason(present: bool, mocap: np.ndarray, model: np.ndarray) -> str:
    if not present:
        return NOT_TRACKED
    if not np.all(np.isfinite(mocap)):
        return NOT_FINITE
    return "" if pose_is_valid(model) else OUT_OF_BOUNDS


def _result(model: np.ndarray, reasons: tuple[str, str]) -> ModelFrameHands:
    valid = np.array([reason == "" for reason in reasons])
    joints = np.where(valid[:, None, None], model, 0.0).astype(np.float32)
    return ModelFrameHands(joints, valid, reasons)
