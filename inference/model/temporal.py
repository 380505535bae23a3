"""Temporal transformer: divided space-time attention over a clip (full bidirectional in time)."""
from __future__ import annotations

import math

import torch
from torch import nn


class SinusoidalPositionalEncoding(nn.Module):
    """Buffer `pe` (1, max_len, D): pe[p, 2k] = sin(p · exp(−2k ln 10000 / D)), pe[p, 2k+1] = cos(…)."""

    def __init__(self, width: int, max_len: int) -> None:
        super().__init__()
        position = torch.arange(max_len, dtype=torch.float32)[:, None]
        div = torch.exp(torch.arange(0, width, 2, dtype=torch.float32) * (-math.log(10000.0) / width))
        pe = torch.zeros(1, max_len, width)
        pe[0, :, 0::2] = torch.sin(position * div)
        pe[0, :, 1::2] = torch.cos(position * div)
        self.register_buffer("pe", pe)


def feed_forward(width: int, mlp_ratio: float, dropout: float) -> nn.Sequential:
    """Linear → GELU → Dropout → Linear → Dropout (keys .0 and .3)."""
    hidden = int(width * mlp_ratio)
    return nn.Sequential(nn.Linear(width, hidden), nn.GELU(), nn.Dropout(dropout), nn.Linear(hidden, width), nn.Dropout(dropout))


class DividedSpaceTimeLayer(nn.Module):
    """Pre-norm: attention across time per patch, then across patches per frame, then the MLP."""

    def __init__(self, width: int, heads: int, mlp_ratio: float, dropout: float) -> None:
        super().__init__()
        self.temporal_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.temporal_norm = nn.LayerNorm(width)
        self.spatial_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.spatial_norm = nn.LayerNorm(width)
        self.mlp = feed_forward(width, mlp_ratio, dropout)
        self.mlp_norm = nn.LayerNorm(width)

    def time_mixing(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, N, D) → (B, T, N, D) after the temporal attention residual."""
        b, t, n, d = x.shape
        xt = x.permute(0, 2, 1, 3).reshape(b * n, t, d)
        h = self.temporal_norm(xt)
        xt = xt + self.temporal_attn(h, h, h, need_weights=False)[0]
        return xt.reshape(b, n, t, d).permute(0, 2, 1, 3)

    def frame_mixing(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, N, D) → (B, T, N, D): spatial attention and MLP residuals, each frame on its own."""
        b, t, n, d = x.shape
        xs = x.reshape(b * t, n, d)
        h = self.spatial_norm(xs)
        xs = xs + self.spatial_attn(h, h, h, need_weights=False)[0]
        xs = xs + self.mlp(self.mlp_norm(xs))
        return xs.reshape(b, t, n, d)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.frame_mixing(self.time_mixing(x))


class TemporalTransformer(nn.Module):
    """(B, T, N, D) → (B, T, N, D), T ≤ window_size."""

    def __init__(self, width: int, layers: int, heads: int, mlp_ratio: float, dropout: float, window_size: int) -> None:
        super().__init__()
        self.input_proj = nn.Linear(width, width)
        self.temporal_pos_encoding = SinusoidalPositionalEncoding(width, window_size)
        self.layers = nn.ModuleList(DividedSpaceTimeLayer(width, heads, mlp_ratio, dropout) for _ in range(layers))
        self.norm = nn.LayerNorm(width)

    def embed(self, x: torch.Tensor) -> torch.Tensor:
        """Input projection plus the temporal position table (the same for every patch)."""
        t = x.shape[1]
        return self.input_proj(x) + self.temporal_pos_encoding.pe[:, :t, None, :]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = self.embed(x)
        for layer in self.layers:
            x = layer(x)
        return self.norm(x)
