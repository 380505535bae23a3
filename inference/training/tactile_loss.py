"""The official TactileLoss: contact-weighted masked MSE + L1 + total variation, weights from `training.loss`."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import torch

from touchanything.inference.model.config_sections import limits

WEIGHT = limits(0.0)


@dataclass(frozen=True)
class TactileLossConfig:
    """`training.loss` (official names and values): the masked terms are weighted `contact_weight`× where
    the target exceeds `pressure_threshold`."""

    UNUSED: ClassVar = ("pose_loss_weight", "use_confidence_weighting")  # the pose task's loss settings
    mse_weight: float = field(default=1.0, metadata=WEIGHT)
    l1_weight: float = field(default=0.5, metadata=WEIGHT)
    tv_weight: float = field(default=0.01, metadata=WEIGHT)
    contact_weight: float = field(default=3.0, metadata=WEIGHT)
    pressure_threshold: float = field(default=0.1, metadata=limits(0.0, 1.0, high_open=True))


def tactile_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor,
                 weights: TactileLossConfig = TactileLossConfig()) -> torch.Tensor:
    """pred, target, mask: (B, T, 2, 21, 21); mask is 1 at sensor cells. The masked terms divide by the
    number of valid cells (not the weight sum); TV is over the whole prediction, unmasked. The caller skips
    batches whose mask is empty (the division would be 0/0)."""
    w = weights
    weight = (1.0 + (w.contact_weight - 1.0) * (target > w.pressure_threshold).float()) * mask
    count = mask.sum()
    diff = pred - target
    masked = w.mse_weight * (weight * diff.square()).sum() / count + w.l1_weight * (weight * diff.abs()).sum() / count
    tv = (pred[..., 1:, :] - pred[..., :-1, :]).abs().mean() + (pred[..., :, 1:] - pred[..., :, :-1]).abs().mean()
    return masked + w.tv_weight * tv
