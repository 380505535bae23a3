"""MultiViewEncoder: per-view backbone tokens plus a view embedding, fused per frame by a softmax gate."""
from __future__ import annotations

import torch
from torch import nn

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.model.vision_encoder import VisionEncoder


def encoder_layers(width: int, heads: int, layers: int, mlp_ratio: float, dropout: float) -> nn.TransformerEncoder:
    """The official pre-norm GELU `nn.TransformerEncoder` stack (no final norm)."""
    layer = nn.TransformerEncoderLayer(width, heads, int(width * mlp_ratio), dropout, activation="gelu",
                                       batch_first=True, norm_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


class MultiViewEncoder(nn.Module):
    """views {name: (B, T, 3, H, W)} (any subset of ego, wrist_left, wrist_right) → (B, T, N, D).

    Absent views are simply not in the dict. One view: output_norm(tokens + view embedding). Several: the
    cross-view transformer over per-view mean tokens gives softmax gates over the present views; the
    output is output_norm of the gate-weighted sum of per-view tokens. Training drops each wrist view with
    probability `view_dropout` (one draw per call, ego always kept).
    """

    def __init__(self, vision_encoder: VisionEncoder, width: int, heads: int, layers: int, mlp_ratio: float,
                 dropout: float, view_dropout: float) -> None:
        super().__init__()
        self.vision_encoder = vision_encoder
        self.view_embeddings = nn.ParameterDict({v: nn.Parameter(torch.randn(1, 1, 1, width) * 0.02) for v in VIEW_NAMES})
        self.cross_view_transformer = encoder_layers(width, heads, layers, mlp_ratio, dropout)
        self.view_gate = nn.Sequential(nn.Linear(width, width // 4), nn.GELU(), nn.Linear(width // 4, 1))
        self.output_norm = nn.LayerNorm(width)
        self.view_dropout = view_dropout
        self.last_kept: tuple[str, ...] = ()

    def kept_views(self, views: dict[str, torch.Tensor]) -> list[str]:
        """Present views in the official order, after view dropout when training (kept in `last_kept`)."""
        order = [v for v in VIEW_NAMES if v in views]
        if self.training:
            order = [v for v in order if v == "ego" or torch.rand(1).item() > self.view_dropout] or order[:1]
        self.last_kept = tuple(order)
        return order

    def backbone_tokens(self, views: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """{view: (B, T, 3, H, W)} → {view: (B, T, N, D)} backbone tokens of the kept views (view dropout
        applies when training)."""
        return {v: self.vision_encoder(views[v]) for v in self.kept_views(views)}

    def fuse_tokens(self, tokens: dict[str, torch.Tensor]) -> torch.Tensor:
        """{view: (B, T, N, D)} backbone tokens → (B, T, N, D): view embeddings added, fused, normalised."""
        return self.fuse({v: tokens[v] + self.view_embeddings[v] for v in tokens})

    def fuse(self, encoded: dict[str, torch.Tensor]) -> torch.Tensor:
        """{view: (B, T, N, D)} already encoded → (B, T, N, D) fused and normalised."""
        order = [v for v in VIEW_NAMES if v in encoded]
        b, t, n, d = encoded[order[0]].shape
        if len(order) == 1:
            fused = encoded[order[0]]
        else:
            flat = [encoded[v].reshape(b * t, n, d) for v in order]
            summary = torch.stack([f.mean(dim=1) for f in flat], dim=1)
            weights = torch.softmax(self.view_gate(self.cross_view_transformer(summary)).squeeze(-1), dim=-1)
            fused = sum(weights[:, i, None, None] * f for i, f in enumerate(flat)).reshape(b, t, n, d)
        return self.output_norm(fused)

    def forward(self, views: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.fuse_tokens(self.backbone_tokens(views))


def view_slots(pooled: torch.Tensor, view_ids: torch.Tensor) -> torch.Tensor:
    """pooled (..., V, D) one vector per present view, view_ids (V,) their indices in VIEW_NAMES
    → (..., 3, D): each view's vector in its VIEW_NAMES slot, zeros in the slots of absent views."""
    placement = torch.nn.functional.one_hot(view_ids, len(VIEW_NAMES)).to(pooled.dtype)  # (V, 3)
    return torch.einsum("...vd,vs->...sd", pooled, placement)


def pooled_view_slots(tokens: dict[str, torch.Tensor]) -> torch.Tensor:
    """{view: (B, T, N, D)} backbone tokens of the present views → (B, T, 3, D) each view's mean token in its
    VIEW_NAMES slot (`view_slots`)."""
    order = [v for v in VIEW_NAMES if v in tokens]
    pooled = torch.stack([tokens[v].mean(dim=2) for v in order], dim=2)
    ids = torch.tensor([VIEW_NAMES.index(v) for v in order], device=pooled.device)
    return view_slots(pooled, ids)
