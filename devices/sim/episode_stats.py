"""Per-episode statistics for the dataset card: contact per hand and task, contact visibility per camera, and
the true and estimated hand poses behind the pose-ambiguity statistic (`pose_ambiguity`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.devices.sim.cameras import Camera
from touchanything.devices.sim.hand_model import HandState
from touchanything.devices.sim.shapes import Shape
from touchanything.devices.sim.visibility import visible

CAMERAS = ("chest", "left", "right")
"""The cameras' names in `camera_matrix.txt` and the dataset card, in `VIEW_NAMES` order."""
CONTACT = 0.1


@dataclass
class EpisodeStats:
    """Counts for the dataset card; contact means a tactile cell above 0.1 (before the glove).
    contact["<hand>/<action>"] = [frames in contact, frames];
    visible["<camera>/<hand>"] = [contact points visible from the camera, contact points of that hand];
    per frame and hand (T, 2): poses (T, 2, 21, 3) true head-camera joints (metres, float32), touching,
    pose_valid (the WiLoR hand is valid), pose_error (RMS joint error of the WiLoR pose, metres), hidden
    (share of joints hidden from the head camera), labels (action names)."""

    folder: Path
    scene: str
    task: str
    objects: list[str]
    frames: int
    unseen: bool
    dead_column: int | None
    contact: dict = field(default_factory=dict)
    visible: dict = field(default_factory=dict)
    poses: np.ndarray | None = None
    touching: np.ndarray | None = None
    pose_valid: np.ndarray | None = None
    pose_error: np.ndarray | None = None
    hidden: np.ndarray | None = None
    labels: np.ndarray | None = None

    def start_poses(self, labels: np.ndarray) -> None:
        """Allocate the per-frame records; `labels` (T, 2) action names."""
        frames = self.frames
        self.poses = np.zeros((frames, 2, 21, 3), np.float32)
        self.touching = np.zeros((frames, 2), bool)
        self.pose_valid = np.zeros((frames, 2), bool)
        self.pose_error = np.zeros((frames, 2), np.float32)
        self.hidden = np.zeros((frames, 2), np.float32)
        self.labels = labels.astype(str)

    def record_frame(self, k: int, hands: list[HandState], pressure: np.ndarray, cameras: list[Camera],
                     objects: list[Shape], sample_visibility: bool) -> None:
        """Contact per hand and task at frame k; visibility of the contact points from each camera when
        `sample_visibility`."""
        for h, hand in enumerate(hands):
            touching = (np.nan_to_num(pressure[h]) > CONTACT) & ~np.isnan(hand.cell_points[..., 0])
            self.touching[k, h] = touching.any()
            entry = self.contact.setdefault(f"{HANDS[h]}/{self.labels[k, h]}", [0, 0])
            entry[0] += int(touching.any())
            entry[1] += 1
            self.poses[k, h] = cameras[0].to_camera(hand.joints)
            if not (touching.any() and sample_visibility):
                continue
            points = hand.cell_points[touching]
            for name, camera in zip(CAMERAS, cameras):
                entry = self.visible.setdefault(f"{name}/{HANDS[h]}", [0, 0])
                entry[0] += int(visible(camera, points, objects, hands).sum())
                entry[1] += len(points)

    def record_estimate(self, k: int, h: int, model_joints: np.ndarray, valid: bool, hidden: float) -> None:
        """The metric head-camera joints (21, 3) of the pose the model reads for hand h at frame k."""
        self.pose_valid[k, h] = valid
        self.hidden[k, h] = hidden
        self.pose_error[k, h] = np.sqrt(np.mean(np.sum((model_joints - self.poses[k, h]) ** 2, axis=-1)))
