"""Test videos with bare hands: the reference image `hand0.jpg` (a right hand, ../shared/reference/hands, MIT)
and its mirror image (a left hand) moving across a textured background, written through the project's
video writer. Test data only: the images are read from ../shared, never copied into the project."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from touchanything.devices.episodes.video_io import VideoWriter

HANDS_DIR = Path(__file__).resolve().parents[3] / "shared" / "reference" / "hands"
SIZE = (480, 640)


def reference_image(name: str) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a reference image; the calling test is skipped when ../shared is not beside the
    checkout."""
    if not HANDS_DIR.is_dir():
        pytest.skip("../shared/reference/hands is not beside the checkout")
    return cv2.cvtColor(cv2.imread(str(HANDS_DIR / name)), cv2.COLOR_BGR2RGB)


def background(size: tuple[int, int] = SIZE, seed: int = 0) -> np.ndarray:
    """A smooth, slightly textured picture (a wall), (H, W, 3) uint8 RGB."""
    h, w = size
    y, x = np.mgrid[0:h, 0:w]
    image = np.stack([120 + 40 * np.sin(x / 90.0), 110 + 30 * np.cos(y / 70.0), 100 + 20 * np.sin((x + y) / 120.0)], -1)
    image += np.random.default_rng(seed).normal(0, 4, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8)


def paste(frame: np.ndarray, image: np.ndarray, x: int, y: int) -> None:
    frame[y:y + image.shape[0], x:x + image.shape[1]] = image


def hand_frame(k: int, empty: int) -> np.ndarray:
    """Frame k: the background, then from frame `empty` on the left hand (mirrored hand0.jpg) at the image's
    left and the right hand (hand0.jpg) at its right, moving towards each other and back (3 px per frame, 60 px
    at most, never overlapping) and up and down."""
    frame = background()
    if k >= empty:
        right = reference_image("hand0.jpg")
        t = k - empty
        step = 60 - abs(3 * t % 120 - 60)
        bob = round(40 * np.sin(t / 12))
        paste(frame, np.ascontiguousarray(right[:, ::-1]), 30 + step, 128 + bob)
        paste(frame, right, 386 - step, 128 - bob)
    return frame


def write_hand_video(path: Path, frames: int = 24, empty: int = 4) -> Path:
    """An MP4 of `frames` frames at 30 fps (640×480): `empty` frames without hands, then both hands moving
    (any length)."""
    with VideoWriter(path, crf=18) as writer:
        for k in range(frames):
            writer.write(hand_frame(k, empty))
    return path
