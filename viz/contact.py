"""Contact lamps as an image (the comparison video's): per hand, does the prediction and does the measurement
say "in contact", and do they agree — as a frame's `FrameFacts` decided it (`viz.frame_facts`)."""
from __future__ import annotations

import functools

import cv2
import numpy as np

from touchanything.core.snapshot import HANDS
from touchanything.viz.frame_facts import FrameFacts
from touchanything.viz.pressure_panel import BACKGROUND, put_text

ON, OFF, UNKNOWN = (60, 200, 90), (90, 90, 110), (60, 60, 80)
AGREE, DISAGREE = (160, 230, 160), (255, 140, 120)


def lamp_colour(contact: bool | None) -> tuple[int, int, int]:
    """Green in contact, grey not, dark unknown (no prediction of the hand, no glove map of it)."""
    return UNKNOWN if contact is None else ON if contact else OFF


def verdict(agree: bool | None) -> tuple[str, tuple[int, int, int]]:
    """The agreement's word and colour: "ok", "miss", or "" when unknown."""
    return ("", AGREE) if agree is None else ("ok", AGREE) if agree else ("miss", DISAGREE)


def contact_badges(facts: FrameFacts, width: int, height: int) -> np.ndarray:
    """(height, width, 3) uint8: a row per hand with a predicted and a measured lamp (`lamp_colour`) and the
    verdict (`verdict`)."""
    image = _badge_frame(width, height).copy()
    row = max(height // 3, 14)
    radius = max(min(row // 3, 12), 3)
    for h, hand in enumerate(facts.hands):
        y = row * (h + 2) - row // 2
        for k, contact in enumerate((hand.contact_predicted, hand.contact_measured)):
            _disc(image, lamp_centre(k, h, width, row), radius, lamp_colour(contact))
        word, colour = verdict(hand.agree)
        if word:
            put_text(image, word, (width - 46, y + 5), 0.4, colour)
    return image


def lamp_centre(k: int, h: int, width: int, row: int) -> tuple[int, int]:
    """Where lamp `k` (0 predicted, 1 measured) of hand `h` is in a `contact_badges` image."""
    return width // 3 + 14 + k * (width // 3 - 10), row * (h + 2) - row // 2


@functools.lru_cache(maxsize=8)
def _badge_frame(width: int, height: int) -> np.ndarray:
    """The labels (text rendering is the slow part, so drawn once per size)."""
    image = np.empty((height, width, 3), np.uint8)
    image[:] = BACKGROUND
    row = max(height // 3, 14)
    put_text(image, "contact", (8, row - 6), 0.45)
    put_text(image, "pred", (width // 3, row - 6), 0.4)
    put_text(image, "meas", (2 * width // 3 - 10, row - 6), 0.4)
    for h, label in enumerate(HANDS):
        put_text(image, label, (8, row * (h + 2) - row // 2 + 5), 0.45)
    image.flags.writeable = False
    return image


def _disc(image: np.ndarray, centre: tuple[int, int], radius: int, colour: tuple[int, int, int]) -> None:
    cv2.circle(image, centre, radius, colour, -1, cv2.LINE_AA)
    cv2.circle(image, centre, radius, (0, 0, 0), 1, cv2.LINE_AA)
