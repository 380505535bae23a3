"""The streaming engine's two halves of any model: the per-frame encoder and the window head.

`model_halves(model) -> (encoder, head)`, two modules with the contracts of `FrameEncoder` and `WindowHead`:
encoder(images (V, 3, S, S), view_ids (V,)) → frame tokens (N, D); head(frame_tokens (T, N, D), joints
(P, J, 3), joint_ids (J,), positions (P,)) → (P, J // 21, 21, 21). TouchAnything splits as described in
`frame_encoder` and `window_head`; the single-frame baseline's tokens are its per-frame view slots (N = 1)
and its head looks at the output frames only.
"""
from __future__ import annotations

import torch
from torch import nn

from touchanything.inference.engine.frame_encoder import FrameEncoder
from touchanything.inference.engine.window_head import WindowHead
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.single_frame_baseline import SingleFrameBaseline


class BaselineFrameEncoder(nn.Module):
    def __init__(self, model: SingleFrameBaseline) -> None:
        super().__init__()
        self.model = model

    def forward(self, images: torch.Tensor, view_ids: torch.Tensor) -> torch.Tensor:
        return self.model.encode_frame(images, view_ids)


class BaselineWindowHead(nn.Module):
    def __init__(self, model: SingleFrameBaseline) -> None:
        super().__init__()
        self.model = model

    def forward(self, frame_tokens: torch.Tensor, joints: torch.Tensor, joint_ids: torch.Tensor,
                positions: torch.Tensor) -> torch.Tensor:
        return self.model.head_at(frame_tokens, joints, joint_ids, positions)


def model_halves(model: TactileModel) -> tuple[nn.Module, nn.Module]:
    """(per-frame encoder, window head) sharing the model's own modules (no copied weights)."""
    if isinstance(model, SingleFrameBaseline):
        return BaselineFrameEncoder(model), BaselineWindowHead(model)
    return FrameEncoder(model), WindowHead(model)
