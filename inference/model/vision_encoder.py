"""VisionEncoder: the backbone (DINOv2 ViT, or the conv extension) applied frame by frame, returning normalised
patch tokens."""
from __future__ import annotations

import torch
from torch import nn

from touchanything.inference.model.conv_backbone import CONV_BACKBONES, ConvBackbone
from touchanything.inference.model.model_config import ModelConfig
from touchanything.inference.model.vit import BACKBONES, DinoVisionTransformer


def backbone(config: ModelConfig) -> DinoVisionTransformer | ConvBackbone:
    """The configured per-frame backbone: an official DINOv2 ViT, or a conv backbone (project extension)."""
    if config.vision_encoder.type == "conv":
        return ConvBackbone(CONV_BACKBONES[config.backbone], config.image_size)
    return DinoVisionTransformer(BACKBONES[config.backbone])


class VisionEncoder(nn.Module):
    """(B, T, 3, H, W) ImageNet-normalised frames → (B, T, N, D) `x_norm_patchtokens` (CLS dropped).

    A frozen backbone runs without gradients and stays in eval mode even when the model trains.
    """

    def __init__(self, encoder: DinoVisionTransformer | ConvBackbone, freeze: bool) -> None:
        super().__init__()
        self.encoder = encoder
        self.freeze = freeze
        if freeze:
            for parameter in self.encoder.parameters():
                parameter.requires_grad = False

    def train(self, mode: bool = True) -> VisionEncoder:
        super().train(mode)
        if self.freeze:
            self.encoder.eval()
        return self

    def forward(self, frames: torch.Tensor) -> torch.Tensor:
        b, t = frames.shape[:2]
        flat = frames.reshape(b * t, *frames.shape[2:])
        with torch.set_grad_enabled(torch.is_grad_enabled() and not self.freeze):
            tokens = self.encoder.forward_features(flat)["x_norm_patchtokens"]
        return tokens.reshape(b, t, *tokens.shape[1:])
