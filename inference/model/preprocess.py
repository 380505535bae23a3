"""Model inputs: frames resized with cv2 INTER_LINEAR (as the official inference) and ImageNet-normalised."""
from __future__ import annotations

import cv2
import numpy as np
import torch

IMAGENET_MEAN = torch.tensor([0.485, 0.456, 0.406]).view(3, 1, 1)
IMAGENET_STD = torch.tensor([0.229, 0.224, 0.225]).view(3, 1, 1)


def resize_frame(image: np.ndarray, size: int) -> np.ndarray:
    """(H, W, 3) uint8 RGB → (size, size, 3) uint8, aspect ratio ignored (as the official transform)."""
    if image.shape[:2] == (size, size):
        return image
    return cv2.resize(image, (size, size), interpolation=cv2.INTER_LINEAR)


def to_model_input(frames: np.ndarray) -> torch.Tensor:
    """(..., S, S, 3) uint8 → (..., 3, S, S) float32: /255 then ImageNet mean/std."""
    x = torch.from_numpy(np.ascontiguousarray(frames)).float().div_(255.0)
    x = x.movedim(-1, -3)
    return (x - IMAGENET_MEAN) / IMAGENET_STD
