"""TouchAnything: the official module tree and state_dict names, and its forward pass.

`model(frames=None, poses=None, views=None) -> {"tactile": (B, T, 2, 21, 21)}`. `views` is a dict with any
subset of ego, wrist_left, wrist_right, each (B, T, 3, H, W); `poses` (B, T, 42, 3) prepared with
`prepare_poses`. The official `frames=` path (ego only, no view embedding, no output norm) is kept.
The backbone is shared, so it appears in the state_dict under both `vision_encoder.encoder.*` and
`multi_view_encoder.vision_encoder.encoder.*`.
"""
from __future__ import annotations

import torch
from torch import nn

from touchanything.inference.model.fusion import CrossAttentionFusion
from touchanything.inference.model.model_config import NUM_JOINTS, TACTILE_SIZE, ModelConfig
from touchanything.inference.model.multi_view import MultiViewEncoder, pooled_view_slots
from touchanything.inference.model.pose_encoder import TransformerPoseEncoder
from touchanything.inference.model.tactile_decoder import JointLevelTactileDecoder, MlpTactileDecoder
from touchanything.inference.model.temporal import TemporalTransformer
from touchanything.inference.model.vision_encoder import VisionEncoder, backbone


class TouchAnything(nn.Module):
    def __init__(self, config: ModelConfig) -> None:
        super().__init__()
        c = config.check()
        self.config = c
        width, mv, tt, pe, fu = c.embed_dim, c.multi_view, c.temporal_transformer, c.pose_encoder, c.fusion
        self.vision_encoder = VisionEncoder(backbone(c), c.vision_encoder.freeze)
        self.multi_view_encoder = MultiViewEncoder(self.vision_encoder, width, mv.num_heads, mv.num_cross_layers,
                                                   mv.mlp_ratio, mv.dropout, mv.view_dropout_prob)
        self.temporal_transformer = TemporalTransformer(width, tt.num_layers, tt.num_heads, tt.mlp_ratio, tt.dropout,
                                                        tt.window_size)
        self.pose_encoder = TransformerPoseEncoder(width, pe.num_layers, pe.num_heads, pe.mlp_ratio, pe.dropout, NUM_JOINTS,
                                                   pe.input)
        self.fusion = CrossAttentionFusion(width, fu.num_layers, fu.num_heads, fu.mlp_ratio, fu.dropout)
        self.view_slots = c.tactile_decoder.type == "mlp_skip_views"
        if c.tactile_decoder.type in ("mlp_skip", "mlp_skip_views"):
            self.decoder = MlpTactileDecoder(width, c.tactile_decoder.conv_channels, c.tactile_decoder.dropout, TACTILE_SIZE,
                                             self.pose_encoder.pose_scale.numel(), 3 * width if self.view_slots else 0)
        else:
            self.decoder = JointLevelTactileDecoder(width, c.tactile_decoder.conv_channels, c.tactile_decoder.dropout, TACTILE_SIZE)

    def forward(self, frames: torch.Tensor | None = None, poses: torch.Tensor | None = None,
                views: dict[str, torch.Tensor] | None = None,
                tokens: dict[str, torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
        """`tokens` (not in the official signature): backbone tokens {view: (B, T, N, D)} computed
        beforehand (a frozen backbone's cache), used instead of `views`."""
        if poses is None:
            raise ValueError("poses (B, T, 42, 3) are required for tactile prediction")
        if views is not None:
            visual = self.encode_frames(views)
        elif tokens is not None:
            kept = self.multi_view_encoder.kept_views(tokens)
            visual = self.encode_tokens({v: tokens[v] for v in kept})
        elif frames is not None:
            visual = self.vision_encoder(frames)
            visual = torch.cat([visual, pooled_view_slots({"ego": visual})], dim=2) if self.view_slots else visual
        else:
            raise ValueError("give views={...}, tokens={...} or frames=")
        return {"tactile": self.head(visual, poses)}

    @property
    def frame_token_shape(self) -> tuple[int, int]:
        """(N, D) of the per-frame half's output: one token per backbone patch, then, for the `mlp_skip_views`
        decoder, the three pooled view slots."""
        return self.config.patches + (3 if self.view_slots else 0), self.config.embed_dim

    @property
    def last_kept(self) -> tuple[str, ...]:
        """The views the last training forward pass used (after view dropout)."""
        return self.multi_view_encoder.last_kept

    def encode_frames(self, views: dict[str, torch.Tensor]) -> torch.Tensor:
        """{view: (B, T, 3, S, S)} → (B, T, N, D) fused visual tokens (the per-frame half), followed for the
        `mlp_skip_views` decoder by the kept views' pooled backbone tokens in their three slots."""
        return self.encode_tokens(self.multi_view_encoder.backbone_tokens(views))

    def encode_tokens(self, tokens: dict[str, torch.Tensor]) -> torch.Tensor:
        """`encode_frames` from the kept views' backbone tokens {view: (B, T, N, D)}."""
        fused = self.multi_view_encoder.fuse_tokens(tokens)
        return torch.cat([fused, pooled_view_slots(tokens)], dim=2) if self.view_slots else fused

    def set_pose_statistics(self, poses) -> int:
        """The `hand` pose input's standardisation from prepared training poses (N, 42, 3); 0 for `camera`."""
        return self.pose_encoder.set_statistics(poses)

    def head(self, visual: torch.Tensor, poses: torch.Tensor) -> torch.Tensor:
        """`encode_frames`'s tokens (B, T, N, D) and prepared poses (B, T, 42, 3) → (B, T, 2, 21, 21)."""
        slots = None
        if self.view_slots:
            visual, slots = visual[:, :, :-3], visual[:, :, -3:]
        fused = self.fusion(self.temporal_transformer(visual), self.pose_encoder(poses))
        if isinstance(self.decoder, MlpTactileDecoder):
            return self.decoder(fused, self.pose_encoder.normalised(poses), slots)
        return self.decoder(fused)
