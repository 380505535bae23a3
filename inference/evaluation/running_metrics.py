"""Official metrics while a replay runs: cumulative over every frame so far and rolling over the last N."""
from __future__ import annotations

from collections import deque

import numpy as np

from touchanything.inference.evaluation.metrics import CONTACT_THRESHOLD, MetricAccumulator, reported_metrics


class RunningMetrics:
    """`add(pred, gt)` per frame ((2, 21, 21) each, NaN outside the layout); `cumulative()` and `rolling()`
    give the six reported official metrics (`METRICS`; NaN where undefined, e.g. no contact yet). A seek should `reset()`.
    `threshold`: the contact threshold (official 0.1).

    Each frame's metric sums are kept as one small vector, so the rolling window is a sum of `window`
    vectors, not a recomputation over its frames: cheap enough to ask for on every displayed frame."""

    def __init__(self, bend: np.ndarray, window: int = 90, threshold: float = CONTACT_THRESHOLD) -> None:
        self.bend = bend
        self.window = window
        self.threshold = threshold
        self._keys = tuple(self._accumulator().sums)
        self.reset()

    def _accumulator(self) -> MetricAccumulator:
        return MetricAccumulator(self.bend, self.threshold)

    def reset(self) -> None:
        self._total = np.zeros(len(self._keys))
        self._recent: deque[np.ndarray] = deque(maxlen=self.window)
        self.frames = 0

    def add(self, pred: np.ndarray, gt: np.ndarray) -> None:
        frame = self._accumulator()
        frame.add(pred[None], gt[None])
        sums = np.array([frame.sums[k] for k in self._keys], np.float64)
        self._total += sums
        self._recent.append(sums)
        self.frames += 1

    def _result(self, sums: np.ndarray) -> dict[str, float]:
        return reported_metrics(dict(zip(self._keys, sums.tolist())))

    def cumulative(self) -> dict[str, float]:
        return self._result(self._total)

    def rolling(self) -> dict[str, float]:
        return self._result(np.sum(self._recent, axis=0) if self._recent else np.zeros(len(self._keys)))
