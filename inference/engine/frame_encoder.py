"""The per-frame half of TouchAnything: backbone per present view, view fusion, temporal input projection.

Everything here depends on one frame only, so the streaming engine computes it once per frame and caches
it. It reuses the model's own modules (no copied weights), so it is exact by construction.
"""
from __future__ import annotations

import torch
from torch import nn

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.model.multi_view import view_slots
from touchanything.inference.model.touch_model import TouchAnything
from touchanything.inference.model.vit import DinoVisionTransformer, interpolate_pos_embed


class FrameEncoder(nn.Module):
    """images (V, 3, S, S) ImageNet-normalised, view_ids (V,) int64 indices into VIEW_NAMES, in that order
    → (N, D) `temporal_transformer.input_proj(multi_view_encoder(...))` for one frame; for the `mlp_skip_views`
    decoder followed by the three pooled view slots (`multi_view.view_slots`), as `encode_frames` gives them.

    With V = 1 the softmax gate is exactly 1, so this equals the official single-view path
    (output_norm(tokens + view embedding)) bit for bit; with V ≥ 2 it is the official gated fusion.
    """

    def __init__(self, model: TouchAnything) -> None:
        super().__init__()
        self.backbone = model.vision_encoder.encoder
        self.multi_view = model.multi_view_encoder
        self.input_proj = model.temporal_transformer.input_proj
        self.view_slots = model.view_slots

    def view_embedding_table(self) -> torch.Tensor:
        """(3, 1, D) view embeddings in VIEW_NAMES order."""
        return torch.cat([self.multi_view.view_embeddings[v] for v in VIEW_NAMES]).reshape(len(VIEW_NAMES), 1, -1)

    def forward(self, images: torch.Tensor, view_ids: torch.Tensor) -> torch.Tensor:
        tokens = self.backbone.forward_features(images)["x_norm_patchtokens"]
        encoded = tokens + self.view_embedding_table()[view_ids]
        summary = encoded.mean(dim=1)[None]
        gates = self.multi_view.view_gate(self.multi_view.cross_view_transformer(summary)).squeeze(-1)
        weights = torch.softmax(gates, dim=-1)[0]
        fused = (weights[:, None, None] * encoded).sum(dim=0)
        visual = self.input_proj(self.multi_view.output_norm(fused))
        if self.view_slots:
            return torch.cat([visual, view_slots(tokens.mean(dim=1), view_ids)])
        return visual


def bake_position_embedding(model: TouchAnything) -> None:
    """Replace the backbone's position table by its interpolation for the model's input size, so the
    forward pass skips the bicubic resize (used for ONNX export; the outputs do not change). A conv backbone
    has one position table of its own size already."""
    backbone = model.vision_encoder.encoder
    if not isinstance(backbone, DinoVisionTransformer):
        return
    grid = model.config.image_size // model.config.patch_size
    with torch.no_grad():
        baked = interpolate_pos_embed(backbone.pos_embed, grid, grid).clone()
    backbone.pos_embed = nn.Parameter(baked, requires_grad=False)
