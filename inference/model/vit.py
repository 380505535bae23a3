"""DINOv2-compatible Vision Transformer (patch 14, LayerScale, qkv bias, LayerNorm eps 1e-6).

Parameter names are those of the official DINOv2 checkpoints (`dinov2_vit{s,b}14_pretrain.pth`), so they
load strictly. Position embeddings are stored for 518 px (37×37 patches) and interpolated for other input
sizes exactly as DINOv2 does: bicubic, no antialias, scale factor (n + 0.1) / 37.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from touchanything.core.errors import UserError

PATCH = 14
PRETRAIN_SIZE = 518
INTERPOLATE_OFFSET = 0.1


@dataclass(frozen=True)
class VitSpec:
    """width (embedding dim), depth (blocks), heads."""

    width: int
    depth: int
    heads: int


BACKBONES = {
    "dinov2_vits14": VitSpec(384, 12, 6),
    "dinov2_vitb14": VitSpec(768, 12, 12),
    "dinov2_vitl14": VitSpec(1024, 24, 16),
    "vit_t14": VitSpec(192, 6, 3),
    "vit_n14": VitSpec(128, 4, 2),
}
"""The official DINOv2 S/14, B/14 and L/14 shapes, and two small widths for CPU real time (trained from
scratch; no pretrained weights exist for them)."""


class PatchEmbed(nn.Module):
    def __init__(self, width: int) -> None:
        super().__init__()
        self.proj = nn.Conv2d(3, width, kernel_size=PATCH, stride=PATCH)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.proj(x).flatten(2).transpose(1, 2)


class Attention(nn.Module):
    def __init__(self, width: int, heads: int) -> None:
        super().__init__()
        self.heads = heads
        self.qkv = nn.Linear(width, 3 * width, bias=True)
        self.proj = nn.Linear(width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, n, c = x.shape
        q, k, v = self.qkv(x).reshape(b, n, 3, self.heads, c // self.heads).permute(2, 0, 3, 1, 4)
        return self.proj(F.scaled_dot_product_attention(q, k, v).transpose(1, 2).reshape(b, n, c))


class Mlp(nn.Module):
    def __init__(self, width: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(width, 4 * width)
        self.act = nn.GELU()
        self.fc2 = nn.Linear(4 * width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


class LayerScale(nn.Module):
    def __init__(self, width: int, init: float = 1e-5) -> None:
        super().__init__()
        self.gamma = nn.Parameter(torch.full((width,), init))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.gamma


class Block(nn.Module):
    def __init__(self, width: int, heads: int) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(width, eps=1e-6)
        self.attn = Attention(width, heads)
        self.ls1 = LayerScale(width)
        self.norm2 = nn.LayerNorm(width, eps=1e-6)
        self.mlp = Mlp(width)
        self.ls2 = LayerScale(width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x + self.ls1(self.attn(self.norm1(x)))
        return x + self.ls2(self.mlp(self.norm2(x)))


def interpolate_pos_embed(pos_embed: torch.Tensor, grid_h: int, grid_w: int) -> torch.Tensor:
    """(1, 1 + M², D) → (1, 1 + grid_h · grid_w, D), as DINOv2's `interpolate_pos_encoding`."""
    n = pos_embed.shape[1] - 1
    m = int(math.sqrt(n))
    if grid_h == m and grid_w == m:
        return pos_embed
    dtype = pos_embed.dtype
    cls, patches = pos_embed[:, :1].float(), pos_embed[:, 1:].float()
    dim = patches.shape[-1]
    scale = ((grid_h + INTERPOLATE_OFFSET) / m, (grid_w + INTERPOLATE_OFFSET) / m)
    patches = F.interpolate(patches.reshape(1, m, m, dim).permute(0, 3, 1, 2), scale_factor=scale,
                            mode="bicubic", antialias=False)
    if patches.shape[-2:] != (grid_h, grid_w):
        raise ValueError(f"position-embedding interpolation gave {tuple(patches.shape[-2:])}, expected {(grid_h, grid_w)}")
    return torch.cat([cls, patches.permute(0, 2, 3, 1).reshape(1, -1, dim)], dim=1).to(dtype)


class DinoVisionTransformer(nn.Module):
    """Input (B, 3, H, W) with H, W multiples of 14 → `forward_features` dict with `x_norm_patchtokens`."""

    def __init__(self, spec: VitSpec) -> None:
        super().__init__()
        self.spec = spec
        self.patch_embed = PatchEmbed(spec.width)
        grid = PRETRAIN_SIZE // PATCH
        self.cls_token = nn.Parameter(torch.zeros(1, 1, spec.width))
        self.pos_embed = nn.Parameter(torch.zeros(1, 1 + grid * grid, spec.width))
        self.mask_token = nn.Parameter(torch.zeros(1, spec.width))
        self.blocks = nn.ModuleList(Block(spec.width, spec.heads) for _ in range(spec.depth))
        self.norm = nn.LayerNorm(spec.width, eps=1e-6)
        self.head = nn.Identity()
        nn.init.trunc_normal_(self.pos_embed, std=0.02)
        nn.init.normal_(self.cls_token, std=1e-6)

    def forward_features(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        b, _, h, w = x.shape
        tokens = torch.cat([self.cls_token.expand(b, -1, -1), self.patch_embed(x)], dim=1)
        tokens = tokens + interpolate_pos_embed(self.pos_embed, h // PATCH, w // PATCH)
        for block in self.blocks:
            tokens = block(tokens)
        tokens = self.norm(tokens)
        return {"x_norm_clstoken": tokens[:, 0], "x_norm_patchtokens": tokens[:, 1:]}


def load_dinov2_weights(model: DinoVisionTransformer, path: Path) -> None:
    """Load an official `dinov2_vit*14_pretrain.pth` strictly from a local file (never downloaded)."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: DINOv2 weights not found (download the official file once and pass its path)")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for a file that is not a checkpoint
        raise UserError(f"{path}: not a readable PyTorch checkpoint ({exc.__class__.__name__})") from None
    expected = model.state_dict()
    wrong = sorted(set(expected) ^ set(state)) + [k for k in expected if k in state and state[k].shape != expected[k].shape]
    if wrong:
        raise UserError(f"{path}: DINOv2 weights do not match {model.spec} (first differing keys: {', '.join(wrong[:4])})")
    model.load_state_dict(state, strict=True)
