"""The window half of TouchAnything: temporal transformer, pose encoder, fusion and decoder, computed only
for the output positions of an 8-frame window.

Only the temporal attention mixes frames. All temporal layers but the last must run on every frame of the
window (the position table shifts as the window slides); the last layer's temporal attention is computed
with queries at the output positions only, and everything after it (spatial attention, MLP, final norm,
pose encoder, fusion, decoder) is per frame, so it runs for the output frames alone. The outputs equal the
batch forward of the same clip at those positions (float rounding aside).
"""
from __future__ import annotations

import torch
from torch import nn

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.inference.model.tactile_decoder import MlpTactileDecoder
from touchanything.inference.model.temporal import DividedSpaceTimeLayer
from touchanything.inference.model.touch_model import TouchAnything


def time_mixing_at(layer: DividedSpaceTimeLayer, x: torch.Tensor, positions: torch.Tensor) -> torch.Tensor:
    """(T, N, D) window → (P, N, D): the layer's temporal-attention residual at `positions` only."""
    xt = x.permute(1, 0, 2)
    h = layer.temporal_norm(xt)
    query = h.index_select(1, positions)
    mixed = xt.index_select(1, positions) + layer.temporal_attn(query, h, h, need_weights=False)[0]
    return mixed.permute(1, 0, 2)


class WindowHead(nn.Module):
    """frame_tokens (T, N, D) from `FrameEncoder` (for the `mlp_skip_views` decoder the last three are the pooled
    view slots, read by the decoder at the output positions), joints (P, J, 3) prepared poses of the output frames,
    joint_ids (J,) int64 (0–20 left, 21–41 right; J = 21 or 42), positions (P,) int64 in [0, T)
    → (P, J // 21, 21, 21) pressure in [0, 1], hands in joint_ids order.

    J = 42 with ids 0…41 is the official model; J = 21 predicts one hand without the other's joints.
    """

    def __init__(self, model: TouchAnything) -> None:
        super().__init__()
        self.temporal = model.temporal_transformer
        self.pose_encoder = model.pose_encoder
        self.fusion = model.fusion
        self.decoder = model.decoder
        self.view_slots = model.view_slots

    def encode_poses(self, joints: torch.Tensor, joint_ids: torch.Tensor) -> torch.Tensor:
        """(P, J, 3) → (P, J, D): the pose encoder on the selected joints."""
        return self.pose_encoder.encode(joints, joint_ids)

    def visual_at(self, frame_tokens: torch.Tensor, positions: torch.Tensor) -> torch.Tensor:
        """(T, N, D) → (P, N, D) temporal-transformer output at the output positions."""
        t = frame_tokens.shape[0]
        x = frame_tokens + self.temporal.temporal_pos_encoding.pe[0, :t, None, :]
        *full, last = self.temporal.layers
        for layer in full:
            x = layer(x[None])[0]
        x = last.frame_mixing(time_mixing_at(last, x, positions)[None])[0]
        return self.temporal.norm(x)

    def forward(self, frame_tokens: torch.Tensor, joints: torch.Tensor, joint_ids: torch.Tensor,
                positions: torch.Tensor) -> torch.Tensor:
        views = None
        if self.view_slots:
            frame_tokens, slots = frame_tokens[:, :-3], frame_tokens[:, -3:]
            views = self.decoder.hand_views(slots.index_select(0, positions), joint_ids[::JOINTS_PER_HAND] // JOINTS_PER_HAND)
        visual = self.visual_at(frame_tokens, positions)
        fused = self.fusion(visual[None], self.encode_poses(joints, joint_ids)[None])[0]
        feats = self.decoder.joint_proj(fused)
        p, j, c = feats.shape
        per_hand = feats.reshape(p * (j // JOINTS_PER_HAND), JOINTS_PER_HAND, c)
        if isinstance(self.decoder, MlpTactileDecoder):
            pose = self.pose_encoder.normalised(joints)
            hands = self.decoder.hand(per_hand, pose.reshape(p * (j // JOINTS_PER_HAND), JOINTS_PER_HAND, -1), views)
        else:
            hands = self.decoder.hand(per_hand)
        return hands.reshape(p, j // JOINTS_PER_HAND, *hands.shape[-2:])
