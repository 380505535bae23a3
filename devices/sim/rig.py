"""The simulated rig's frames and mounts: how its Rokoko and Vive streams relate to the world, and the
`[pose]` calibration (touchanything.devices.rig.pose_transform) that a scene file would carry for it.

- Rokoko (`rokoko_hands.json`): world joints with the axes reordered (x, z, y), i.e. Studio's Y up,
  Z forward (a left-handed frame: the reordering is a reflection), metres, same origin as the world.
- Vive (`vive_poses.json`): poses in a tracking universe laid out like OpenVR's standing universe (x right,
  Y up, Z backward), its origin on the floor behind the person and turned by a yaw against the table.
- The chest tracker is rigidly mounted with the head camera; the wrist trackers are the hand frames.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from touchanything.devices.rig.pose_transform import PoseCalibration
from touchanything.devices.sim.cameras import HEAD_FOCAL, HEIGHT, WIDTH
from touchanything.devices.sim.shapes import inverse, pose_at

ROKOKO_AXES = (0, 2, 1)
"""Rokoko coordinates = world coordinates in this order."""
CAMERA_IN_CHEST_TRANS = (0.0, 0.12, -0.03)
"""The head camera's origin in the chest tracker's frame (y up, z backward): 12 cm above, 3 cm in front."""
CAMERA_IN_CHEST_EULER_DEG = (130.0, 3.0, -2.0)
"""The head camera's orientation in the chest tracker's frame, scipy extrinsic "xyz" Euler angles: the
130° turn about x points the camera forward and 50° down; the mount is 3° and 2° crooked."""
STANDING_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""Columns: the standing universe's x (right), y (up) and z (backward) in world coordinates, before yaw."""
TRACKING_ORIGIN_IN_WORLD = (0.4, -1.1, -0.75)
"""The tracking universe's origin in the world: on the floor (0.75 m below the table top), behind the person."""
TRACKING_YAW_DEG = 25.0
"""The tracking universe is turned this much about the vertical against the table."""


def quat_wxyz(rotation: np.ndarray) -> np.ndarray:
    """A 3×3 rotation as a (4,) float32 quaternion w, x, y, z."""
    return Rotation.from_matrix(rotation).as_quat(scalar_first=True).astype(np.float32)


def rokoko_joints(world_joints: np.ndarray) -> np.ndarray:
    """(..., 3) world points → Rokoko Studio coordinates (float32), as `rokoko_hands.json` stores them."""
    return world_joints[..., list(ROKOKO_AXES)].astype(np.float32)


def camera_in_chest() -> np.ndarray:
    """4×4 chest-from-camera transform of the rigid mount."""
    rotation = Rotation.from_euler("xyz", CAMERA_IN_CHEST_EULER_DEG, degrees=True).as_matrix()
    return pose_at(CAMERA_IN_CHEST_TRANS, rotation)


def tracking_from_world() -> np.ndarray:
    """4×4 transform from world to tracking-universe coordinates."""
    yaw = Rotation.from_euler("z", TRACKING_YAW_DEG, degrees=True).as_matrix()
    return inverse(pose_at(TRACKING_ORIGIN_IN_WORLD, yaw @ STANDING_AXES))


def tracker_poses(camera_pose: np.ndarray, hand_poses: np.ndarray) -> np.ndarray:
    """(3, 7) float32 chest, left wrist, right wrist in the tracking universe: trans + rot (w, x, y, z),
    from the head camera's and the hands' 4×4 world poses."""
    tracking = tracking_from_world()
    chest = camera_pose @ inverse(camera_in_chest())
    poses = [tracking @ pose for pose in (chest, *hand_poses)]
    return np.stack([np.concatenate([p[:3, 3], quat_wxyz(p[:3, :3])]) for p in poses]).astype(np.float32)


def rig_calibration() -> PoseCalibration:
    """The `[pose]` calibration of the simulated rig (the truth the streams were made with)."""
    tracking = tracking_from_world()
    rokoko_from_world = np.eye(3)[list(ROKOKO_AXES)]
    matrix = np.hstack([tracking[:3, :3] @ rokoko_from_world.T, tracking[:3, 3:]])
    mount = camera_in_chest()
    return PoseCalibration(
        tracking_from_mocap=tuple(tuple(row) for row in matrix.tolist()),
        camera_in_chest_trans=tuple(mount[:3, 3].tolist()),
        camera_in_chest_wxyz=tuple(Rotation.from_matrix(mount[:3, :3]).as_quat(scalar_first=True).tolist()),
        image_size=(WIDTH, HEIGHT),
        focal_px=float(HEAD_FOCAL),
    )
