"""Model inputs: frames resized with cv2 INTER_LINEAR (as the official inference) and ImageNet-normalised, and the
black frames of the pose-only baseline."""
from __future__ import annotations

import cv2
import numpy as np
import torch

IMAGENET_MEAN = torch.tensor([0.485, 0.456, 0.406]).view(3, 1, 1)
IMAGENET_STD = torch.tensor([0.229, 0.224, 0.225]).view(3, 1, 1)


def blank_frames(shape: tuple[int, ...]) -> np.ndarray:
    """Black uint8 RGB frames of `shape` (..., H, W, 3): every pixel 0 in every channel. The pose-only baseline
    shows these in place of every camera frame of every view a configuration uses (the views stay present),
    through the same preprocessing; black resizes to black, so blanking before or after `resize_frame` gives
    the same model input, (0 − mean) / std per channel."""
    return np.zeros(shape, np.uint8)


def blank_images(images: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """{view: image} → the same views, each a black frame of its image's shape (`blank_frames`)."""
    return {view: blank_frames(image.shape) for view, image in images.items()}


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


def model_input(frames: list[np.ndarray], size: int) -> np.ndarray:
    """Views of one frame, each (H, W, 3) uint8 RGB of any size → (V, 3, S, S) float32 model input (CPU, cv2)."""
    return to_model_input(np.stack([resize_frame(frame, size) for frame in frames])).numpy()


def model_input_on_device(frames: list[np.ndarray], size: int, device: torch.device) -> torch.Tensor:
    """The same as `model_input`, computed on `device`: each frame is uploaded as uint8, resized there with
    bilinear half-pixel sampling (cv2 INTER_LINEAR's rule, without its 11-bit fixed-point weights), rounded
    to whole intensities as cv2 does, then ImageNet-normalised. Agrees with `model_input` within 1/255 of
    an intensity before normalisation (the fixed-point rounding); docs/engine.md has the measured bound."""
    mean, std = IMAGENET_MEAN.to(device), IMAGENET_STD.to(device)
    out = []
    for frame in frames:
        x = torch.from_numpy(np.ascontiguousarray(frame)).to(device, non_blocking=True).permute(2, 0, 1)[None].float()
        if frame.shape[:2] != (size, size):
            x = torch.nn.functional.interpolate(x, size=(size, size), mode="bilinear", align_corners=False)
            x = x.round_().clamp_(0, 255)
        out.append(x[0])
    return (torch.stack(out).div_(255.0) - mean) / std
