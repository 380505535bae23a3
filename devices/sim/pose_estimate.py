"""WiLoR-like estimation error for the hand poses the streams carry; the physics and the touch use the truth.

A monocular hand-pose estimator such as WiLoR gets the hand's shape roughly right and its distance along the
camera ray poorly (it infers depth from the hand's apparent size), its errors drift rather than flicker, and
they grow when the hand is hidden. The estimate of a hand is the kinematic hand re-posed with
- smooth errors (unit Ornstein–Uhlenbeck processes with a 0.5 s time constant, so they do not average out
  over the model's 0.5 s window), σ for a hand the head camera sees whole: the wrist's distance along the
  camera ray off by 3.5 % (≈ 1.7 cm at the workspace), 4 mm across the ray, the hand's orientation by 4°
  about the wrist (≈ 1 cm at the fingertips), each finger's flexion by 0.05;
- all of it (1 + 1.5 · h) times larger when a share h of its joints is hidden from the head camera (outside
  the image, or behind an object, the table or the other hand);
- per frame (`wilor_joints`): 3 mm per joint coordinate and 2 % on the WiLoR wrist depth.
The Rokoko stream carries the same smooth estimate (without the per-frame part), so the two pose sources
agree up to WiLoR's per-frame jitter, as the rig calibration checks expect.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from touchanything.devices.rig.pose_transform import wilor_from_camera
from touchanything.devices.sim.cameras import Camera
from touchanything.devices.sim.hand_model import HandState, hand_joints
from touchanything.devices.sim.shapes import Shape, pose_at
from touchanything.devices.sim.visibility import visible

TIME_CONSTANT = 0.5
DEPTH_SHARE = 0.035
LATERAL = 0.004
ROTATION_DEG = 4.0
FLEXION = 0.05
OCCLUDED_GAIN = 1.5
JITTER = 0.003
DEPTH_JITTER = 0.02
CHANNELS = 11
"""Smooth error channels per hand: depth share, two lateral, three rotation, five flexion."""


def smooth_noise(rng: np.random.Generator, frames: int, fps: float) -> np.ndarray:
    """(frames, 2, CHANNELS) unit-variance Ornstein–Uhlenbeck processes (stationary from the first frame)."""
    decay = np.exp(-1.0 / (fps * TIME_CONSTANT))
    steps = rng.normal(size=(frames, 2, CHANNELS))
    out = np.empty_like(steps)
    out[0] = steps[0]
    for k in range(1, frames):
        out[k] = decay * out[k - 1] + np.sqrt(1.0 - decay ** 2) * steps[k]
    return out


def hidden_share(camera: Camera, joints: np.ndarray, objects: list[Shape], other: HandState) -> float:
    """Share of a hand's (21, 3) joints the camera does not see (outside the image, or behind an object, the
    table or the `other` hand; the hand's own parts do not count)."""
    return 1.0 - float(visible(camera, joints, objects, [other]).mean())


def estimate_joints(side: str, pose: np.ndarray, flexion: np.ndarray, camera: Camera, noise: np.ndarray,
                    hidden: float) -> np.ndarray:
    """(21, 3) world joints of the estimate of a hand (true wrist `pose`, `flexion` (5,)) seen by `camera`,
    from its smooth error channels `noise` (CHANNELS,) at this frame and its hidden share."""
    gain = 1.0 + OCCLUDED_GAIN * hidden
    wrist = pose[:3, 3]
    ray = wrist - camera.centre
    along = ray / np.linalg.norm(ray)
    across = camera.pose[:3, 0] - along * (camera.pose[:3, 0] @ along)
    across /= np.linalg.norm(across)
    shift = DEPTH_SHARE * noise[0] * ray + LATERAL * (noise[1] * across + noise[2] * np.cross(along, across))
    turn = Rotation.from_rotvec(gain * np.radians(ROTATION_DEG) * noise[3:6]).as_matrix()
    return hand_joints(side, pose_at(wrist + gain * shift, turn @ pose[:3, :3]), flexion + gain * FLEXION * noise[6:])


def wilor_joints(camera: Camera, joints: np.ndarray, depth_scale: float, rng: np.random.Generator) -> np.ndarray:
    """(21, 3) float32 WiLoR-convention joints of estimated world joints, with the per-frame jitter."""
    out = wilor_from_camera(camera.to_camera(joints), depth_scale * rng.normal(1.0, DEPTH_JITTER))
    return (out + rng.normal(0.0, JITTER, out.shape)).astype(np.float32)


def camera_from_wilor(joints: np.ndarray, depth_scale: float) -> np.ndarray:
    """The inverse of `wilor_from_camera`: (..., 21, 3) WiLoR-convention joints → metric head-camera joints."""
    root = joints[..., :1, :]
    return (joints - root) + root * np.array([1.0, 1.0, 1.0 / depth_scale])
