"""The Snapshot record: everything the rig knows at one 30 Hz tick, and the official stream names."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

VIEW_NAMES = ("ego", "wrist_left", "wrist_right")
"""Camera views in the official order (the model's `views` dict keys)."""

HANDS = ("left", "right")
TRACKER_ROLES = ("chest", "left_wrist", "right_wrist")
FPS = 30
FRAME_PERIOD_US = 1_000_000 // FPS
"""Official synthetic timestamps: t_i = i * 33333 µs."""
POSE_FROM_WILOR, POSE_FROM_ROKOKO, POSE_FROM_MOCAP, POSE_FROM_CAMERA = (
    "WiLoR file", "Rokoko file", "mocap", "camera estimate")
"""A Snapshot's `pose_source`: recorded WiLoR or Rokoko poses, the live mocap, the ego camera's estimate."""


@dataclass
class Snapshot:
    """One tick of the rig.

    frame_index: episode frame (replay) or tick counter (live).
    t_us: capture time on the host monotonic clock in µs; latency = now − t_us.
    images: {view: (H, W, 3) uint8 RGB} for the views present.
    joints: (42, 3) float32, left 0–20 then right 21–41 in the official joint order, in the frame of the
        selected pose source (WiLoR: head-camera frame); an invalid hand holds zeros.
    joints_valid: (2,) bool per hand [left, right].
    pressure_raw: (2, 256) uint8 raw glove vectors, when a glove stream exists.
    pressure_grid: (2, 21, 21) float32 ground truth in [0, 1], NaN outside the layout, when known.
    imu_wxyz: (2, 4) float32 glove quaternions (w, x, y, z), when known.
    trackers: {role: (7,) float32 trans + rot}.
    source_status: {source: short human-readable status}.
    glove_present: (2,) bool, which rows of `pressure_raw` hold a real sample (an absent glove's row is
        zeros); None = every row that `pressure_raw` has.
    mocap_joints: (42, 3) float32 hand-mocap joints before any transform (Rokoko Studio axes, metres),
        zeros where invalid, with mocap_valid (2,) bool; None when the rig has no mocap.
    source_age_ms: {source: age of the sample used (or refused as stale)} at `t_us`, for live sources.
    pose_source: where `joints` come from (one of the POSE_FROM_* names), "" when nothing provides them.
    joints_confidence: (2,) float32 per-hand confidence of an estimated pose in [0, 1] (0 where not found);
        None for recorded and mocap poses.
    stage_ms: {stage: ms} time spent on this snapshot by stages before the engine (e.g. "hand pose").
    """

    frame_index: int
    t_us: int
    images: dict[str, np.ndarray]
    joints: np.ndarray
    joints_valid: np.ndarray
    pressure_raw: np.ndarray | None = None
    pressure_grid: np.ndarray | None = None
    imu_wxyz: np.ndarray | None = None
    trackers: dict[str, np.ndarray] = field(default_factory=dict)
    source_status: dict[str, str] = field(default_factory=dict)
    glove_present: np.ndarray | None = None
    mocap_joints: np.ndarray | None = None
    mocap_valid: np.ndarray | None = None
    source_age_ms: dict[str, float] = field(default_factory=dict)
    pose_source: str = ""
    joints_confidence: np.ndarray | None = None
    stage_ms: dict[str, float] = field(default_factory=dict)
