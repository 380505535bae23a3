"""Which detected hand is the person's left and which the right, frame after frame, and their smoothing.

MediaPipe's Tasks API labels each hand it finds "Left" or "Right": the person's own hand for an unmirrored
image. "Left" goes to joints 0–20 and "Right" to 21–41; a mirrored image (a selfie webcam preview) swaps
them (`mirror`). Two detections with one label keep the more confident. A label that flips for a hand that
is being followed (its landmarks close to where a hand was in the previous frame) is believed only after
`handedness_frames` frames in a row (hysteresis), so a flicker of the classifier does not swap the hands.
The joints of a hand followed from the previous frame are smoothed exponentially (`smoothing`: the weight of
the previous value; 0 = none). A hand that is not found is not valid (zeros), never a stale or zero pose
marked valid.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.core.hand_pose import JOINTS_PER_HAND

LABELS = ("Left", "Right")
"""MediaPipe's handedness labels in the model's hand order (an unmirrored image)."""
FOLLOW_DISTANCE = 0.15
"""A detection continues a hand of the previous frame when its landmarks lie within this mean distance
(a fraction of the image's longer side) of that hand's."""


@dataclass(frozen=True)
class HandDetection:
    """One hand found in a frame: `label` "Left" | "Right" as MediaPipe gives it, `score` its handedness
    confidence in [0, 1], `joints` (21, 3) in WiLoR's camera frame, `pixels` (21, 2) image landmarks."""

    label: str
    score: float
    joints: np.ndarray
    pixels: np.ndarray


@dataclass(frozen=True)
class TrackedHands:
    """joints (2, 21, 3) float32 [left, right] in WiLoR's camera frame, zeros where not valid; valid (2,)
    bool; confidence (2,) float32 handedness score of each valid hand (0 where not found); pixels (2, 21, 2)
    image landmarks (NaN where not found)."""

    joints: np.ndarray
    valid: np.ndarray
    confidence: np.ndarray
    pixels: np.ndarray


class HandTracks:
    """`update(detections, width, height)` per frame in order; `reset()` before an unrelated frame (a seek)."""

    def __init__(self, mirror: bool = False, smoothing: float = 0.5, handedness_frames: int = 5) -> None:
        self.mirror, self.smoothing, self.handedness_frames = mirror, smoothing, handedness_frames
        self.reset()

    def reset(self) -> None:
        self._joints: list[np.ndarray | None] = [None, None]
        self._pixels: list[np.ndarray | None] = [None, None]
        self._disagree = [0, 0]

    def slot_of(self, label: str) -> int:
        """0 (left) or 1 (right) for MediaPipe's label, with the mirror setting applied."""
        return LABELS.index(label) ^ int(self.mirror)

    def update(self, detections: list[HandDetection], width: int, height: int) -> TrackedHands:
        """The hands of this frame from its detections (see the module docstring for the rules)."""
        scale = float(max(width, height))
        slots = [self._slot(d, scale) for d in detections]
        kept: dict[int, tuple[HandDetection, bool]] = {}
        for detection, (slot, followed) in zip(detections, slots):
            if slot not in kept or detection.score > kept[slot][0].score:
                kept[slot] = (detection, followed)
        joints = np.zeros((2, JOINTS_PER_HAND, 3), np.float32)
        pixels = np.full((2, JOINTS_PER_HAND, 2), np.nan, np.float32)
        confidence = np.zeros(2, np.float32)
        for slot in range(2):
            if slot not in kept:
                self._joints[slot] = self._pixels[slot] = None
                self._disagree[slot] = 0
                continue
            detection, followed = kept[slot]
            new = np.asarray(detection.joints, np.float64)
            previous = self._joints[slot]
            smoothed = new if previous is None or not followed else self.smoothing * previous + (1 - self.smoothing) * new
            self._joints[slot], self._pixels[slot] = smoothed, np.asarray(detection.pixels, np.float64)
            joints[slot], pixels[slot], confidence[slot] = smoothed, detection.pixels, detection.score
        return TrackedHands(joints, np.array([0 in kept, 1 in kept]), confidence, pixels)

    def _slot(self, detection: HandDetection, scale: float) -> tuple[int, bool]:
        """(slot, whether the detection continues the hand held in that slot in the previous frame)."""
        labelled = self.slot_of(detection.label)
        followed = self._followed(detection, scale)
        if followed is None:
            return labelled, False
        if followed == labelled:
            self._disagree[followed] = 0
            return followed, True
        self._disagree[followed] += 1
        if self._disagree[followed] < self.handedness_frames:
            return followed, True
        self._disagree[followed] = 0
        return labelled, False

    def _followed(self, detection: HandDetection, scale: float) -> int | None:
        """The slot whose previous hand this detection continues (the nearer one within FOLLOW_DISTANCE)."""
        distances = [np.inf if previous is None else
                     float(np.linalg.norm(np.asarray(detection.pixels) - previous, axis=-1).mean()) / scale
                     for previous in self._pixels]
        nearest = int(np.argmin(distances))
        return nearest if distances[nearest] < FOLLOW_DISTANCE else None
