"""The official offline stitching, streamed: each frame's output is the average over every window that
contains it, emitted once the last window that can contain it (the one ending 14 frames later) is done."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from touchanything.inference.engine.frame_ring import CachedFrame
from touchanything.inference.model.model_config import SPAN


@dataclass
class StitchedFrame:
    """Running sums for one frame; counts are per hand (a hand without a pose adds nothing)."""

    frame: CachedFrame
    total: np.ndarray = field(default_factory=lambda: np.zeros((2, 21, 21), np.float64))
    counts: np.ndarray = field(default_factory=lambda: np.zeros(2, np.int64))
    exact: bool = True

    def mean(self) -> np.ndarray:
        """(2, 21, 21) float32; a hand that was never predicted is 0."""
        return (self.total / np.maximum(self.counts, 1)[:, None, None]).astype(np.float32)


class StitchAccumulator:
    def __init__(self) -> None:
        self._frames: dict[int, StitchedFrame] = {}

    def clear(self) -> None:
        self._frames.clear()

    def add(self, frames: list[CachedFrame], outputs: np.ndarray, hands: np.ndarray, exact: bool) -> None:
        """One window: frames (8), outputs (8, 2, 21, 21), hands (8, 2) bool predicted."""
        for frame, output, predicted in zip(frames, outputs, hands):
            entry = self._frames.setdefault(frame.frame_index, StitchedFrame(frame))
            entry.total[predicted] += output[predicted]
            entry.counts += predicted
            entry.exact &= exact

    def complete(self, newest: int | None = None) -> list[StitchedFrame]:
        """Remove and return, oldest first, the frames no later window can contain (all when newest is None)."""
        done = sorted(i for i in self._frames if newest is None or i <= newest - (SPAN - 1))
        return [self._frames.pop(i) for i in done]
