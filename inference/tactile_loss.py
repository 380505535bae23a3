"""The official TactileLoss: contact-weighted masked MSE + 0.5 · L1 + 0.01 · total variation."""
from __future__ import annotations

import torch

CONTACT_THRESHOLD, CONTACT_WEIGHT = 0.1, 3.0
MSE_WEIGHT, L1_WEIGHT, TV_WEIGHT = 1.0, 0.5, 0.01


def tactile_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """pred, target, mask: (B, T, 2, 21, 21); mask is 1 at sensor cells. The masked terms divide by the
    number of valid cells (not the weight sum); TV is over the whole prediction, unmasked. The caller skips
    batches whose mask is empty (the division would be 0/0)."""
    weight = (1.0 + (CONTACT_WEIGHT - 1.0) * (target > CONTACT_THRESHOLD).float()) * mask
    count = mask.sum()
    diff = pred - target
    masked = MSE_WEIGHT * (weight * diff.square()).sum() / count + L1_WEIGHT * (weight * diff.abs()).sum() / count
    tv = (pred[..., 1:, :] - pred[..., :-1, :]).abs().mean() + (pred[..., :, 1:] - pred[..., :, :-1]).abs().mean()
    return masked + TV_WEIGHT * tv
