"""Contact indicators: per hand, does the prediction and does the measurement say "in contact"?

The rule is the official per-frame contact rule applied to each hand on its own: at least 5 % of the
hand's non-NaN, non-bend cells are strictly above the contact threshold (official threshold 0.1).
"""
from __future__ import annotations

import functools

import cv2
import numpy as np

from touchanything.inference.evaluation.metrics import CONTACT_THRESHOLD, contact_frames
from touchanything.viz.pressure_panel import BACKGROUND, put_text

ON, OFF, UNKNOWN = (60, 200, 90), (90, 90, 110), (60, 60, 80)


def hand_contact(grids: np.ndarray | None, bend: np.ndarray, threshold: float = CONTACT_THRESHOLD) -> np.ndarray | None:
    """(2, 21, 21) grid (NaN outside the layout) → (2,) bool contact per hand; None stays None."""
    if grids is None:
        return None
    return np.array([contact_frames(np.asarray(grids[h])[None, None], bend[h][None], threshold)[0] for h in range(2)])


def contact_badges(predicted: np.ndarray | None, measured: np.ndarray | None, width: int, height: int) -> np.ndarray:
    """(height, width, 3) uint8: a row per hand with a predicted and a measured lamp (green = contact,
    grey = none, dark = unknown) and whether they agree."""
    image = _badge_frame(width, height).copy()
    row = max(height // 3, 14)
    radius = max(min(row // 3, 12), 3)
    for h in range(2):
        y = row * (h + 2) - row // 2
        for k, flags in enumerate((predicted, measured)):
            colour = UNKNOWN if flags is None else (ON if flags[h] else OFF)
            _disc(image, (width // 3 + 14 + k * (width // 3 - 10), y), radius, colour)
        if predicted is not None and measured is not None:
            agree = predicted[h] == measured[h]
            put_text(image, "ok" if agree else "miss", (width - 46, y + 5), 0.4,
                     (160, 230, 160) if agree else (255, 140, 120))
    return image


@functools.lru_cache(maxsize=8)
def _badge_frame(width: int, height: int) -> np.ndarray:
    """The labels (text rendering is the slow part, so drawn once per size)."""
    image = np.empty((height, width, 3), np.uint8)
    image[:] = BACKGROUND
    row = max(height // 3, 14)
    put_text(image, "contact", (8, row - 6), 0.45)
    put_text(image, "pred", (width // 3, row - 6), 0.4)
    put_text(image, "meas", (2 * width // 3 - 10, row - 6), 0.4)
    for h, label in enumerate(("left", "right")):
        put_text(image, label, (8, row * (h + 2) - row // 2 + 5), 0.45)
    image.flags.writeable = False
    return image


def _disc(image: np.ndarray, centre: tuple[int, int], radius: int, colour: tuple[int, int, int]) -> None:
    cv2.circle(image, centre, radius, colour, -1, cv2.LINE_AA)
    cv2.circle(image, centre, radius, (0, 0, 0), 1, cv2.LINE_AA)
