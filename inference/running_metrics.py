"""Official metrics while a replay runs: cumulative over every frame so far and rolling over the last N."""
from __future__ import annotations

from collections import deque

import numpy as np

from inference.metrics import MetricAccumulator


class RunningMetrics:
    """`add(pred, gt)` per frame ((2, 21, 21) each, NaN outside the layout); `cumulative()` and `rolling()`
    give the official metric dict (NaN where undefined, e.g. no contact yet). A seek should `reset()`."""

    def __init__(self, bend: np.ndarray, window: int = 90) -> None:
        self.bend = bend
        self.window = window
        self._total = MetricAccumulator(bend)
        self._recent: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=window)
        self.frames = 0

    def reset(self) -> None:
        self._total = MetricAccumulator(self.bend)
        self._recent.clear()
        self.frames = 0

    def add(self, pred: np.ndarray, gt: np.ndarray) -> None:
        self._total.add(pred[None], gt[None])
        self._recent.append((pred, gt))
        self.frames += 1

    def cumulative(self) -> dict[str, float]:
        return self._total.result()

    def rolling(self) -> dict[str, float]:
        accumulator = MetricAccumulator(self.bend)
        if self._recent:
            accumulator.add(np.stack([p for p, _ in self._recent]), np.stack([g for _, g in self._recent]))
        return accumulator.result()
