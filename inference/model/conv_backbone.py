"""A small convolutional backbone for the CPU presets (a project extension: `model.vision_encoder.type: conv`).

It has the DINOv2 backbone's contract (`forward_features(x)["x_norm_patchtokens"]`), so everything after it —
view embeddings and gate, the temporal transformer, the fusion's cross-attention, the streaming engine's
per-frame cache, ONNX export — is unchanged: its last feature map, one token per cell, is what the fusion
attends to. Trained from scratch; no pretrained weights exist for it.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn


@dataclass(frozen=True)
class ConvSpec:
    """channels: output channels of the stride-2 stages (the input is divided by 2 ** len(channels));
    width: the token width D (a 1×1 projection of the last stage)."""

    channels: tuple[int, ...]
    width: int

    @property
    def stride(self) -> int:
        return 2 ** len(self.channels)


CONV_BACKBONES = {
    "conv_p16": ConvSpec(channels=(8, 16, 32, 64), width=64),
    "conv_n16": ConvSpec(channels=(16, 32, 64, 128), width=128),
    "conv_t16": ConvSpec(channels=(24, 48, 96, 192), width=192),
}
"""`conv_p16` (width 64, the `pico` preset), `conv_n16` (width 128, `nano`) and `conv_t16` (width 192, `tiny`):
four stride-2 3×3 convolution stages (BatchNorm, ReLU), so a 96 px input gives 6 × 6 = 36 tokens, 64 px 16."""


def _stage(inputs: int, outputs: int) -> nn.Sequential:
    return nn.Sequential(nn.Conv2d(inputs, outputs, 3, stride=2, padding=1, bias=False), nn.BatchNorm2d(outputs),
                         nn.ReLU(inplace=True))


class ConvBackbone(nn.Module):
    """(B, 3, S, S) ImageNet-normalised frames, S a multiple of `spec.stride` → `forward_features` dict with
    `x_norm_patchtokens` (B, (S / stride)², D): the last stage projected to D, plus a learned position
    embedding per cell, LayerNorm'd. Computed in channels-last layout (faster convolutions on the CPU)."""

    def __init__(self, spec: ConvSpec, image_size: int) -> None:
        super().__init__()
        self.spec = spec
        sizes = (3, *spec.channels)
        self.stages = nn.Sequential(*(_stage(a, b) for a, b in zip(sizes, sizes[1:])))
        self.proj = nn.Conv2d(spec.channels[-1], spec.width, 1)
        cells = (image_size // spec.stride) ** 2
        self.pos_embed = nn.Parameter(torch.zeros(1, cells, spec.width))
        self.norm = nn.LayerNorm(spec.width, eps=1e-6)
        nn.init.trunc_normal_(self.pos_embed, std=0.02)

    def forward_features(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        x = self.proj(self.stages(x.contiguous(memory_format=torch.channels_last)))
        tokens = x.flatten(2).transpose(1, 2) + self.pos_embed
        return {"x_norm_patchtokens": self.norm(tokens)}
