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


HAND_VIEW_ORDER = ((0, 1, 2), (0, 2, 1))
"""Per hand (0 left, 1 right), the VIEW_NAMES slots in the order the `mlp_skip_views` decoder reads them: the
chest camera, the hand's own wrist camera, the other wrist camera — so the shared MLP finds each hand's own
wrist view in the same place."""


class MlpTactileDecoder(nn.Module):
    """A project extension (`tactile_decoder.type: mlp_skip` or `mlp_skip_views`) with the joint-level decoder's
    interface: the same per-joint projection to C channels, then per hand the 21 joints' features flattened and
    concatenated with the hand's normalised pose input (21 × `skip` features: a direct path from the pose to the
    cells) and, for `mlp_skip_views` (`views` = 3·D), the three views' pooled backbone tokens in the hand's
    view order (`HAND_VIEW_ORDER`; zeros for an absent or dropped view: a direct path from each camera) →
    Linear(21·C + 21·skip + views, 8·C) → GELU → Linear → 441 cells → sigmoid. No spatial prior and no
    BatchNorm."""

    def __init__(self, width: int, channels: int, dropout: float, size: int, skip: int, views: int = 0) -> None:
        super().__init__()
        self.channels, self.size, self.skip, self.views = channels, size, skip, views
        self.joint_proj = nn.Sequential(nn.Linear(width, channels), nn.GELU(), nn.Dropout(dropout))
        self.cells = nn.Sequential(nn.Linear(21 * (channels + skip) + views, 8 * channels), nn.GELU(), nn.Dropout(dropout),
                                   nn.Linear(8 * channels, size * size), nn.Sigmoid())
        # on the model's device, so that a CUDA-graph capture copies nothing from the CPU; not in the state dict
        self.register_buffer("view_order", torch.tensor(HAND_VIEW_ORDER), persistent=False)

    def hand_views(self, slots: torch.Tensor, hand_ids: torch.Tensor) -> torch.Tensor:
        """slots (N, 3, D) per frame, hand_ids (H,) 0 left / 1 right → (N·H, 3·D), frame-major, each hand's
        slots in its `HAND_VIEW_ORDER`."""
        return slots[:, self.view_order[hand_ids]].reshape(-1, 3 * slots.shape[-1])

    def hand(self, feats: torch.Tensor, pose: torch.Tensor, views: torch.Tensor | None = None) -> torch.Tensor:
        """(M, 21, C) hands' joint features, (M, 21, skip) their normalised pose input and, when the decoder
        reads them, (M, 3·D) their `hand_views` → (M, 1, 21, 21)."""
        parts = [feats.flatten(1), pose.flatten(1)] + ([views] if self.views else [])
        return self.cells(torch.cat(parts, dim=1)).reshape(-1, 1, self.size, self.size)

    def forward(self, fused: torch.Tensor, pose: torch.Tensor, slots: torch.Tensor | None = None) -> torch.Tensor:
        """(B, T, 42, D) fused joint tokens, (B, T, 42, skip) normalised poses and, when the decoder reads them,
        (B, T, 3, D) pooled view slots → (B, T, 2, 21, 21)."""
        b, t, j, d = fused.shape
        x = self.joint_proj(fused.reshape(b * t * 2, 21, d))
        views = None if not self.views else self.hand_views(slots.reshape(b * t, 3, -1), torch.arange(2, device=fused.device))
        out = self.hand(x, pose.reshape(b * t * 2, 21, -1), views)
        return out.reshape(b, t, 2, *out.shape[-2:])
