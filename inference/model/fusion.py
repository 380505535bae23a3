"""Cross-attention fusion: each frame's joints attend to that frame's visual tokens."""
from __future__ import annotations

import torch
from torch import nn

from touchanything.inference.model.temporal import feed_forward


class FusionLayer(nn.Module):
    """Pre-norm: cross-attention (queries = joints, keys/values = visual tokens), self-attention, FFN."""

    def __init__(self, width: int, heads: int, mlp_ratio: float, dropout: float) -> None:
        super().__init__()
        self.cross_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.cross_norm = nn.LayerNorm(width)
        self.self_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.self_norm = nn.LayerNorm(width)
        self.ffn = feed_forward(width, mlp_ratio, dropout)
        self.ffn_norm = nn.LayerNorm(width)
        self.dropout = nn.Dropout(dropout)

    def forward(self, joints: torch.Tensor, visual: torch.Tensor) -> torch.Tensor:
        q = self.cross_norm(joints)
        joints = joints + self.dropout(self.cross_attn(q, visual, visual, need_weights=False)[0])
        q = self.self_norm(joints)
        joints = joints + self.dropout(self.self_attn(q, q, q, need_weights=False)[0])
        return joints + self.ffn(self.ffn_norm(joints))


class CrossAttentionFusion(nn.Module):
    """visual (B, T, N, D) and joints (B, T, 42, D) → (B, T, 42, D); frames never mix here."""

    def __init__(self, width: int, layers: int, heads: int, mlp_ratio: float, dropout: float) -> None:
        super().__init__()
        self.layers = nn.ModuleList(FusionLayer(width, heads, mlp_ratio, dropout) for _ in range(layers))
        self.norm = nn.LayerNorm(width)

    def forward(self, visual: torch.Tensor, joints: torch.Tensor) -> torch.Tensor:
        b, t, j, d = joints.shape
        x, v = joints.reshape(b * t, j, d), visual.reshape(b * t, -1, d)
        for layer in self.layers:
            x = layer(x, v)
        return self.norm(x).reshape(b, t, j, d)
