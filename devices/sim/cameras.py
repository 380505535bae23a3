"""Simulated cameras: a wide pinhole head camera and equidistant-fisheye wrist cameras, 640×480.

Camera frame (OpenCV): x right, y down, z forward. `pose` is the 4×4 world-from-camera transform.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.devices.sim.shapes import inverse, transform

WIDTH, HEIGHT = 640, 480
HEAD_HFOV_DEG = 90.0
HEAD_FOCAL = (WIDTH / 2) / np.tan(np.radians(HEAD_HFOV_DEG / 2))
WRIST_FOCAL = 190.0
"""Equidistant fisheye r = f·θ: θ = 90° lands 298 px from the centre."""
WRIST_MAX_DEG = 95.0
NEAR = 0.02


@dataclass
class Camera:
    name: str
    pose: np.ndarray
    model: str  # pinhole | fisheye
    focal: float
    width: int = WIDTH
    height: int = HEIGHT

    @property
    def centre(self) -> np.ndarray:
        return self.pose[:3, 3]

    @property
    def matrix(self) -> np.ndarray:
        """3×3 intrinsics (for the fisheye: r = focal · θ about the same principal point)."""
        return np.array([[self.focal, 0, self.width / 2], [0, self.focal, self.height / 2], [0, 0, 1.0]])

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        return transform(inverse(self.pose), points)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 3) world points → pixel (N, 2), distance (N,), projectable (N,) (in front / inside the FOV)."""
        p = self.to_camera(np.asarray(points, float).reshape(-1, 3))
        distance = np.linalg.norm(p, axis=-1)
        if self.model == "pinhole":
            ok = p[:, 2] > NEAR
            z = np.where(ok, p[:, 2], 1.0)
            uv = self.focal * p[:, :2] / z[:, None]
        else:
            rho = np.linalg.norm(p[:, :2], axis=-1)
            theta = np.arctan2(rho, p[:, 2])
            ok = (theta < np.radians(WRIST_MAX_DEG)) & (distance > NEAR)
            uv = (self.focal * theta / np.maximum(rho, 1e-12))[:, None] * p[:, :2]
        uv = uv + np.array([self.width / 2, self.height / 2])
        return uv, distance, ok

    def in_image(self, uv: np.ndarray) -> np.ndarray:
        return (uv[:, 0] >= 0) & (uv[:, 0] < self.width) & (uv[:, 1] >= 0) & (uv[:, 1] < self.height)

    def pixel_radius(self, radius: float, distance: np.ndarray) -> np.ndarray:
        """Approximate image radius (px) of a sphere of `radius` metres at `distance`."""
        return self.focal * radius / np.maximum(distance, NEAR)


def look_at(position: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """World-from-camera pose of a camera at `position` looking at `target` (image up ≈ world `up`)."""
    z = np.asarray(target, float) - position
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, z], axis=1)
    pose[:3, 3] = position
    return pose


def head_camera(position: np.ndarray, target: np.ndarray) -> Camera:
    return Camera("chest", look_at(position, target), "pinhole", HEAD_FOCAL)


WRIST_MOUNT = (0.0, -0.03, 0.03)
"""Camera position in the hand frame: on the palm side of the wrist, behind the heel of the palm."""
WRIST_TILT_DEG = 15.0
"""The wrist camera looks along +y (toward the fingers), tilted this much toward the palm side."""


def wrist_camera(side: str, hand_pose: np.ndarray) -> Camera:
    """Fisheye camera on the wrist looking along the palm toward the fingers."""
    tilt = np.radians(WRIST_TILT_DEG)
    forward = np.array([0.0, np.cos(tilt), np.sin(tilt)])
    down = np.array([0.0, np.sin(tilt), -np.cos(tilt)])  # image down = toward the back of the hand
    right = np.cross(down, forward)
    local = np.eye(4)
    local[:3, :3] = np.stack([right, down, forward], axis=1)
    local[:3, 3] = WRIST_MOUNT
    camera_pose = hand_pose @ local
    return Camera(f"{side}", camera_pose, "fisheye", WRIST_FOCAL)
