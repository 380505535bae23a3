"""Colour augmentation of training clips, a project extension (`data.colour_augmentation`, strength s in [0, 1];
0, the default, leaves the frames alone as the official trainer does with `use_augmentation: false`).

Per clip and per view, the same for all T frames of the clip: brightness × U(1 − s, 1 + s), contrast about the
image's mean grey × U(1 − s, 1 + s), saturation × U(1 − s, 1 + s), and with probability s the RGB channels in a
random order (a hue change that keeps the shapes and shadows). Its purpose: an object's colour should not decide
its contact, so that the model carries over to objects it has not seen (docs/findings.md measures it).
"""
from __future__ import annotations

import torch

from touchanything.inference.model.preprocess import IMAGENET_MEAN, IMAGENET_STD

LUMA = (0.299, 0.587, 0.114)


def _uniform(n: int, strength: float, like: torch.Tensor) -> torch.Tensor:
    """(n, 1, 1, 1, 1) factors drawn from U(1 − strength, 1 + strength)."""
    return 1.0 + strength * (2.0 * torch.rand(n, 1, 1, 1, 1, device=like.device, dtype=like.dtype) - 1.0)


def _grey(x: torch.Tensor) -> torch.Tensor:
    """(..., 3, S, S) RGB in [0, 1] → (..., 1, S, S) luma."""
    weights = torch.tensor(LUMA, device=x.device, dtype=x.dtype).view(3, 1, 1)
    return (x * weights).sum(dim=-3, keepdim=True)


def _channel_orders(n: int, strength: float, device: torch.device) -> torch.Tensor:
    """(n, 3) channel orders: a random permutation with probability `strength`, else (0, 1, 2)."""
    orders = torch.argsort(torch.rand(n, 3, device=device), dim=1)
    keep = torch.rand(n, device=device) >= strength
    orders[keep] = torch.arange(3, device=device)
    return orders


def augment_clip(frames: torch.Tensor, strength: float) -> torch.Tensor:
    """frames (B, T, 3, S, S) ImageNet-normalised → the same, each clip's colours changed as the module says.
    Values stay within what an image in [0, 1] normalises to; non-finite input stays non-finite (the loss check
    reports it)."""
    if strength <= 0.0:
        return frames
    mean, std = IMAGENET_MEAN.to(frames).view(3, 1, 1), IMAGENET_STD.to(frames).view(3, 1, 1)
    x = frames * std + mean
    n = x.shape[0]
    x = x * _uniform(n, strength, x)
    level = _grey(x).mean(dim=(-1, -2), keepdim=True)
    x = (x - level) * _uniform(n, strength, x) + level
    grey = _grey(x)
    x = (x - grey) * _uniform(n, strength, x) + grey
    orders = _channel_orders(n, strength, x.device).view(n, 1, 3, 1, 1).expand_as(x)
    x = x.gather(2, orders).clamp(0.0, 1.0)
    return (x - mean) / std


def augment_views(views: dict[str, torch.Tensor], strength: float) -> dict[str, torch.Tensor]:
    """{view: (B, T, 3, S, S)} → each view augmented on its own draw (`augment_clip`)."""
    return {name: augment_clip(frames, strength) for name, frames in views.items()}
