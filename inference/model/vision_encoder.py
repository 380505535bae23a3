"""VisionEncoder: the DINOv2 backbone applied frame by frame, returning normalised patch tokens."""
from __future__ import annotations

import torch
from torch import nn

from touchanything.inference.model.vit import DinoVisionTransformer


class VisionEncoder(nn.Module):
    """(B, T, 3, H, W) ImageNet-normalised frames → (B, T, N, D) `x_norm_patchtokens` (CLS dropped).

    A frozen backbone runs without gradients and stays in eval mode even when the model trains.
    """

    def __init__(self, encoder: DinoVisionTransformer, freeze: bool) -> None:
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
