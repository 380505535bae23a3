"""The single-frame baseline (a project extension, `model.baseline`): the simplest model a reviewer would try.

Per frame, each present view goes through the configured backbone (a small CNN, `vision_encoder.type: conv`)
and its feature map is averaged into one vector; the three views fill fixed slots (zeros for a view that is
absent or dropped). Per hand, an MLP reads those slots and the hand's 21 joints (wrist-relative, plus the
wrist, standardised by the training set: `pose_encoder.hand_features`) and gives its 21×21 map. No time, no
attention. Trained on black frames (`data.blank_images`) it is the pose-only MLP baseline: the CNN then sees
one constant image. It has the interfaces the trainer, evaluation and streaming engine use
(`encode_frames`, `head`, `forward`, `last_kept`, `set_pose_statistics`, and the per-frame and window halves
`encode_frame` and `head_at`).
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from touchanything.core.hand_pose import JOINTS_PER_HAND
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.model.model_config import TACTILE_SIZE, ModelConfig
from touchanything.inference.model.multi_view import view_slots
from touchanything.inference.model.pose_encoder import set_hand_statistics, standardised_hand_features
from touchanything.inference.model.vision_encoder import VisionEncoder

CELLS = TACTILE_SIZE * TACTILE_SIZE


def _mlp(inputs: int, hidden: int, layers: int, dropout: float) -> nn.Sequential:
    """`layers` × (Linear, ReLU, Dropout), then a Linear to the 441 cells and a sigmoid."""
    parts: list[nn.Module] = []
    for i in range(layers):
        parts += [nn.Linear(inputs if i == 0 else hidden, hidden), nn.ReLU(inplace=True), nn.Dropout(dropout)]
    return nn.Sequential(*parts, nn.Linear(hidden, CELLS), nn.Sigmoid())


class SingleFrameBaseline(nn.Module):
    """views {name: (B, T, 3, S, S)} and poses (B, T, 42, 3) → {"tactile": (B, T, 2, 21, 21)}, each frame on its
    own. Visual features per frame: (1, 3·D) — the views' mean tokens in VIEW_NAMES slots."""

    def __init__(self, config: ModelConfig, backbone: nn.Module) -> None:
        super().__init__()
        self.config = config
        b = config.baseline
        self.vision_encoder = VisionEncoder(backbone, config.vision_encoder.freeze)
        self.view_dropout = config.multi_view.view_dropout_prob
        self.register_buffer("pose_offset", torch.zeros(6))
        self.register_buffer("pose_scale", torch.ones(6))
        inputs = len(VIEW_NAMES) * config.embed_dim + JOINTS_PER_HAND * 6
        self.hands = nn.ModuleList(_mlp(inputs, b.hidden, b.layers, b.dropout) for _ in range(2))
        self.last_kept: tuple[str, ...] = ()

    @property
    def frame_token_shape(self) -> tuple[int, int]:
        """(N, D) of the per-frame half's output: one token holding the three view slots."""
        return 1, len(VIEW_NAMES) * self.config.embed_dim

    def set_pose_statistics(self, poses: np.ndarray) -> int:
        """Standardise the pose input by the valid hands of `poses` (N, 42, 3) prepared (`set_hand_statistics`);
        returns their number."""
        return set_hand_statistics(self.pose_offset, self.pose_scale, poses)

    def kept_views(self, views: dict) -> list[str]:
        order = [v for v in VIEW_NAMES if v in views]
        if self.training:
            order = [v for v in order if v == "ego" or torch.rand(1).item() > self.view_dropout] or order[:1]
        self.last_kept = tuple(order)
        return order

    @staticmethod
    def _slots(pooled: torch.Tensor, view_ids: torch.Tensor) -> torch.Tensor:
        """pooled (..., V, D), view_ids (V,) → (..., 1, 3·D): `view_slots` flattened into one token."""
        return view_slots(pooled, view_ids).flatten(-2).unsqueeze(-2)

    def encode_frames(self, views: dict[str, torch.Tensor]) -> torch.Tensor:
        """{view: (B, T, 3, S, S)} → (B, T, 1, 3·D), after view dropout when training."""
        kept = self.kept_views(views)
        pooled = torch.stack([self.vision_encoder(views[v]).mean(dim=2) for v in kept], dim=2)  # (B, T, V, D)
        ids = torch.tensor([VIEW_NAMES.index(v) for v in kept], device=pooled.device)
        return self._slots(pooled, ids)

    def encode_frame(self, images: torch.Tensor, view_ids: torch.Tensor) -> torch.Tensor:
        """The engine's per-frame half: images (V, 3, S, S), view_ids (V,) → (1, 3·D)."""
        pooled = self.vision_encoder.encoder.forward_features(images)["x_norm_patchtokens"].mean(dim=1)
        return self._slots(pooled, view_ids)

    def _maps(self, visual: torch.Tensor, joints: torch.Tensor, hand_ids: torch.Tensor) -> torch.Tensor:
        """visual (N, 3·D), joints (N, H·21, 3) whole hands, hand_ids (H,) 0 left / 1 right → (N, H, 21, 21)."""
        n = joints.shape[0]
        pose = standardised_hand_features(joints, self.pose_offset, self.pose_scale).reshape(n, -1, JOINTS_PER_HAND * 6)
        h = pose.shape[1]
        x = torch.cat([visual[:, None].expand(-1, h, -1), pose], dim=-1)
        both = torch.stack([mlp(x) for mlp in self.hands], dim=2)  # (N, H, 2, 441)
        pick = hand_ids.view(1, h, 1, 1).expand(n, h, 1, CELLS)
        return both.gather(2, pick).reshape(n, h, TACTILE_SIZE, TACTILE_SIZE)

    def head(self, visual: torch.Tensor, poses: torch.Tensor) -> torch.Tensor:
        """visual (B, T, 1, 3·D), poses (B, T, 42, 3) → (B, T, 2, 21, 21)."""
        b, t = poses.shape[:2]
        maps = self._maps(visual.reshape(b * t, -1), poses.reshape(b * t, 42, 3), torch.arange(2, device=poses.device))
        return maps.reshape(b, t, 2, TACTILE_SIZE, TACTILE_SIZE)

    def head_at(self, frame_tokens: torch.Tensor, joints: torch.Tensor, joint_ids: torch.Tensor,
                positions: torch.Tensor) -> torch.Tensor:
        """The engine's window half: frame_tokens (T, 1, 3·D), joints (P, J, 3) of the output frames,
        joint_ids (J,) whole hands, positions (P,) → (P, J // 21, 21, 21)."""
        visual = frame_tokens.index_select(0, positions).flatten(1)
        return self._maps(visual, joints, joint_ids[::JOINTS_PER_HAND] // JOINTS_PER_HAND)

    def forward(self, frames: torch.Tensor | None = None, poses: torch.Tensor | None = None,
                views: dict[str, torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
        if poses is None:
            raise ValueError("poses (B, T, 42, 3) are required for tactile prediction")
        if views is None and frames is not None:
            views = {"ego": frames}
        if views is None:
            raise ValueError("give views={...} or frames=")
        return {"tactile": self.head(self.encode_frames(views), poses)}
