"""Pose encoder (per joint, per frame) and the official pose preparation rules."""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

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


class TransformerPoseEncoder(nn.Module):
    """(B, T, 42, 3) → (B, T, 42, D): fixed normalisation (x/5, y/5, (z−50)/50), per-joint MLP, joint
    position embedding, transformer over the 42 joints of each frame, LayerNorm."""

    def __init__(self, width: int, layers: int, heads: int, mlp_ratio: float, dropout: float, joints: int = 42) -> None:
        super().__init__()
        self.register_buffer("pose_scale", torch.tensor([5.0, 5.0, 50.0]))
        self.register_buffer("pose_offset", torch.tensor([0.0, 0.0, 50.0]))
        self.joint_embed = nn.Sequential(nn.Linear(3, width // 2), nn.GELU(), nn.Linear(width // 2, width))
        self.joint_pos_embed = nn.Parameter(torch.randn(1, joints, width) * 0.02)
        self.transformer = encoder_layers(width, heads, layers, mlp_ratio, dropout)
        self.norm = nn.LayerNorm(width)

    def forward(self, poses: torch.Tensor) -> torch.Tensor:
        b, t, j, _ = poses.shape
        x = (poses.reshape(b * t, j, 3) - self.pose_offset) / self.pose_scale
        x = self.joint_embed(x) + self.joint_pos_embed
        return self.norm(self.transformer(x)).reshape(b, t, j, -1)
