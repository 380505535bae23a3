"""Pose encoder (per joint, per frame) and the official pose preparation rules."""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.inference.model.multi_view import encoder_layers

INVALID_JOINT = -10.0
XY_LIMIT = 10.0
Z_RANGE = (-10.0, 100.0)


def usable_hands(joints: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(..., 2) bool: hands marked valid whose 21 joints are all finite ((..., 42, 3) or (..., 2, 21, 3))."""
    hands = np.asarray(joints).reshape(*np.shape(valid)[:-1], 2, 21, 3)
    return np.asarray(valid, bool) & np.all(np.isfinite(hands), axis=(-1, -2))


def prepare_poses(joints: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Official rules on (..., 42, 3) WiLoR joints and (..., 2) hand validity → float32 model input.

    A hand that is invalid, or holds a NaN/inf, gets all 21 joints at −10; then x, y are clipped to
    [−10, 10] and z to [−10, 100], so the normalised input is bounded whatever the values.
    """
    joints = np.asarray(joints, np.float64).reshape(*np.shape(valid)[:-1], 2, 21, 3).copy()
    joints[~usable_hands(joints, valid)] = INVALID_JOINT
    joints[..., :2] = np.clip(joints[..., :2], -XY_LIMIT, XY_LIMIT)
    joints[..., 2] = np.clip(joints[..., 2], *Z_RANGE)
    return joints.reshape(*joints.shape[:-3], 42, 3).astype(np.float32)


FEATURE_LIMIT = 6.0


def hand_features(joints: torch.Tensor) -> torch.Tensor:
    """(..., J, 3) prepared poses, J a multiple of 21 (whole hands) → (..., J, 6): joint − its hand's wrist
    (joint 0 of each block of 21), then the wrist itself. An invalid hand (all joints −10) gives (0, 0, 0, −10,
    −10, −10) for every joint."""
    shape = joints.shape
    hands = joints.reshape(*shape[:-2], shape[-2] // JOINTS_PER_HAND, JOINTS_PER_HAND, 3)
    wrist = hands[..., :1, :]
    features = torch.cat([hands - wrist, wrist.expand_as(hands)], dim=-1)
    return features.reshape(*shape[:-1], 6)


def standardised_hand_features(joints: torch.Tensor, offset: torch.Tensor, scale: torch.Tensor) -> torch.Tensor:
    """(..., J, 3) prepared poses → (..., J, 6) `hand_features` standardised by offset/scale (6,), clamped to
    ±FEATURE_LIMIT (an invalid hand's −10s stay bounded)."""
    return ((hand_features(joints) - offset) / scale).clamp(-FEATURE_LIMIT, FEATURE_LIMIT)


def hand_statistics(poses: np.ndarray) -> tuple[torch.Tensor, torch.Tensor, int] | None:
    """Mean and standard deviation (floored at 1e-3) of `hand_features` over the valid hands (not all −10)
    of prepared poses (N, 42, 3), and their number; None when there is none."""
    hands = torch.as_tensor(np.asarray(poses, np.float32)).reshape(-1, JOINTS_PER_HAND, 3)
    hands = hands[~(hands == INVALID_JOINT).all(dim=-1).all(dim=-1)]
    if len(hands) == 0:
        return None
    features = hand_features(hands).reshape(-1, 6).double()
    return features.mean(dim=0).float(), features.std(dim=0).nan_to_num(1.0).clamp(min=1e-3).float(), len(hands)


@torch.no_grad()
def set_hand_statistics(offset: torch.Tensor, scale: torch.Tensor, poses: np.ndarray) -> int:
    """Copy `hand_statistics` of the prepared poses (N, 42, 3) into the (6,) buffers `offset` (mean) and `scale`
    (standard deviation). Returns how many valid hands were used (0: the buffers are left unchanged)."""
    stats = hand_statistics(poses)
    if stats is None:
        return 0
    mean, std, count = stats
    offset.copy_(mean)
    scale.copy_(std)
    return count


class TransformerPoseEncoder(nn.Module):
    """(B, T, 42, 3) → (B, T, 42, D): input features normalised with the buffers `pose_offset`/`pose_scale`,
    per-joint MLP, joint position embedding, transformer over the 42 joints of each frame, LayerNorm.

    `inputs` (`model.pose_encoder.input`): `camera` (official) — each joint's WiLoR camera-frame xyz,
    (x, y, z) − (0, 0, 50) divided by (5, 5, 50); `hand` (a project extension) — `hand_features` (each joint
    relative to its hand's wrist, and the wrist's camera-frame position), standardised by the training set's
    statistics (`set_statistics`) and clamped to ±FEATURE_LIMIT."""

    def __init__(self, width: int, layers: int, heads: int, mlp_ratio: float, dropout: float, joints: int = 42,
                 inputs: str = "camera") -> None:
        super().__init__()
        self.inputs = inputs
        if inputs == "camera":
            self.register_buffer("pose_scale", torch.tensor([5.0, 5.0, 50.0]))
            self.register_buffer("pose_offset", torch.tensor([0.0, 0.0, 50.0]))
        else:
            self.register_buffer("pose_scale", torch.ones(6))
            self.register_buffer("pose_offset", torch.zeros(6))
        features = self.pose_scale.numel()
        self.joint_embed = nn.Sequential(nn.Linear(features, width // 2), nn.GELU(), nn.Linear(width // 2, width))
        self.joint_pos_embed = nn.Parameter(torch.randn(1, joints, width) * 0.02)
        self.transformer = encoder_layers(width, heads, layers, mlp_ratio, dropout)
        self.norm = nn.LayerNorm(width)

    def normalised(self, joints: torch.Tensor) -> torch.Tensor:
        """(..., J, 3) prepared poses (whole hands) → (..., J, F) the joint MLP's input."""
        if self.inputs == "camera":
            return (joints - self.pose_offset) / self.pose_scale
        return standardised_hand_features(joints, self.pose_offset, self.pose_scale)

    def set_statistics(self, poses: np.ndarray) -> int:
        """`hand` input: set `pose_offset`/`pose_scale` from the valid hands of `poses` (N, 42, 3) prepared
        (`set_hand_statistics`). Returns how many hands were used (0: nothing changes; always 0 for `camera`)."""
        return set_hand_statistics(self.pose_offset, self.pose_scale, poses) if self.inputs == "hand" else 0

    def encode(self, joints: torch.Tensor, joint_ids: torch.Tensor | slice = slice(None)) -> torch.Tensor:
        """(N, J, 3) → (N, J, D) for the joints `joint_ids` (whole hands) of the 42."""
        x = self.joint_embed(self.normalised(joints)) + self.joint_pos_embed[:, joint_ids]
        return self.norm(self.transformer(x))

    def forward(self, poses: torch.Tensor) -> torch.Tensor:
        b, t, j, _ = poses.shape
        return self.encode(poses.reshape(b * t, j, 3)).reshape(b, t, j, -1)
