"""Event rates and recent means for status displays (thread-safe enough for one writer, many readers)."""
from __future__ import annotations

import time
from collections import deque

import numpy as np


class RateMeter:
    """Events per second over the last `window` events (0 until two events were seen)."""

    def __init__(self, window: int = 30) -> None:
        self._times: deque[float] = deque(maxlen=window)
        self.count = 0

    def tick(self, now: float | None = None) -> None:
        self._times.append(time.monotonic() if now is None else now)
        self.count += 1

    def rate(self) -> float:
        times = tuple(self._times)
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])


class StageMeans:
    """Mean of each named timing over the last `window` reports (a stage absent from a report, because
    it was skipped, does not count as zero)."""

    def __init__(self, window: int = 30) -> None:
        self.window = window
        self._values: dict[str, deque[float]] = {}

    def add(self, timings: dict[str, float]) -> None:
        for name, value in timings.items():
            self._values.setdefault(name, deque(maxlen=self.window)).append(value)

    def means(self) -> dict[str, float]:
        return {name: float(np.mean(tuple(values))) for name, values in list(self._values.items()) if values}
