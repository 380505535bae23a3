"""Joint-level tactile decoder: joint features → an 8×8 grid → convolutions → 21×21 per hand."""
from __future__ import annotations

import torch
from torch import nn

GRID_CELLS = 64


class JointLevelTactileDecoder(nn.Module):
    """(B, T, 42, D) → (B, T, 2, 21, 21) in [0, 1], channel 0 left, 1 right.

    Both hands share the weights (no mirroring) and go through BatchNorm in two separate calls, so in
    training each hand is normalised with its own batch statistics, as in the official code.
    """

    def __init__(self, width: int, channels: int, dropout: float, size: int = 21) -> None:
        super().__init__()
        self.channels = channels
        self.joint_proj = nn.Sequential(nn.Linear(width, channels), nn.GELU(), nn.Dropout(dropout))
        self.joint_grid_weights = nn.Parameter(torch.randn(21, GRID_CELLS) * 0.02)
        self.refine = nn.Sequential(
            nn.Conv2d(channels, channels, 3, padding=1), nn.BatchNorm2d(channels), nn.GELU(),
            nn.Conv2d(channels, 64, 3, padding=1), nn.BatchNorm2d(64), nn.GELU())
        self.upsample = nn.Sequential(
            nn.ConvTranspose2d(64, 32, 4, stride=2, padding=1), nn.BatchNorm2d(32), nn.GELU(),
            nn.Upsample(size=(size, size), mode="bilinear", align_corners=False))
        self.head = nn.Sequential(nn.Conv2d(32, 1, 3, padding=1), nn.Sigmoid())

    def hand(self, feats: torch.Tensor) -> torch.Tensor:
        """(BT, 21, C) one hand's joint features → (BT, 1, 21, 21)."""
        weights = torch.softmax(self.joint_grid_weights, dim=-1)
        grid = torch.einsum("bjc,jg->bgc", feats, weights).reshape(-1, 8, 8, self.channels).permute(0, 3, 1, 2)
        return self.head(self.upsample(self.refine(grid)))

    def forward(self, fused: torch.Tensor) -> torch.Tensor:
        b, t, j, d = fused.shape
        x = self.joint_proj(fused.reshape(b * t, j, d))
        out = torch.cat([self.hand(x[:, :21]), self.hand(x[:, 21:])], dim=1)
        return out.reshape(b, t, 2, *out.shape[-2:])


class MlpTactileDecoder(nn.Module):
    """A project extension (`tactile_decoder.type: mlp_skip`) with the joint-level decoder's interface: the same
    per-joint projection to C channels, then per hand the 21 joints' features flattened and concatenated with
    the hand's normalised pose input (21 × `skip` features: a direct path from the pose to the cells) →
    Linear(21·C + 21·skip, 8·C) → GELU → Linear → 441 cells → sigmoid. No spatial prior and no BatchNorm."""

    def __init__(self, width: int, channels: int, dropout: float, size: int, skip: int) -> None:
        super().__init__()
        self.channels, self.size, self.skip = channels, size, skip
        self.joint_proj = nn.Sequential(nn.Linear(width, channels), nn.GELU(), nn.Dropout(dropout))
        self.cells = nn.Sequential(nn.Linear(21 * (channels + skip), 8 * channels), nn.GELU(), nn.Dropout(dropout),
                                   nn.Linear(8 * channels, size * size), nn.Sigmoid())

    def hand(self, feats: torch.Tensor, pose: torch.Tensor) -> torch.Tensor:
        """(BT, 21, C) one hand's joint features and (BT, 21, skip) its normalised pose input → (BT, 1, 21, 21)."""
        return self.cells(torch.cat([feats.flatten(1), pose.flatten(1)], dim=1)).reshape(-1, 1, self.size, self.size)

    def forward(self, fused: torch.Tensor, pose: torch.Tensor) -> torch.Tensor:
        """(B, T, 42, D) fused joint tokens and (B, T, 42, skip) normalised poses → (B, T, 2, 21, 21)."""
        b, t, j, d = fused.shape
        x = self.joint_proj(fused.reshape(b * t, j, d))
        p = pose.reshape(b * t, j, -1)
        out = torch.cat([self.hand(x[:, :21], p[:, :21]), self.hand(x[:, 21:], p[:, 21:])], dim=1)
        return out.reshape(b, t, 2, *out.shape[-2:])
