"""Event rates and recent means for status displays (thread-safe enough for one writer, many readers).

`RateMeter` is the one rate measurement of the project: every live device (through its latest-value slot),
the rig clock and the engine session count their events with it.
"""
from __future__ import annotations

import time
from collections import deque

import numpy as np


class RateMeter:
    """Events per second over the last `window` events (0 until two events were seen).

    `tick(now)` takes the event's time in seconds on any monotonic clock (default `time.monotonic()`);
    a capture time works as well as an arrival time. Times that go backwards give 0 until they recover.
    """

    def __init__(self, window: int = 30) -> None:
        if window < 2:
            raise ValueError(f"a rate needs a window of at least 2 events, got {window}")
        self._times: deque[float] = deque(maxlen=window)
        self.count = 0

    def tick(self, now: float | None = None, events: int = 1) -> None:
        """Count `events` events that happened at `now` (e.g. several samples completed by one read)."""
        now = time.monotonic() if now is None else now
        self._times.extend([now] * min(events, self._times.maxlen))
        self.count += events

    def rate(self) -> float:
        """Events per second over the window; 0 before two events or when they share one time."""
        times = tuple(self._times)
        if len(times) < 2 or times[-1] <= times[0]:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def reset(self) -> None:
        """Forget the window (after a gap that should not count, e.g. a device that was away); `count` stays."""
        self._times.clear()


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
