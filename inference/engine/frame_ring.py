"""Ring buffer of per-frame engine results and the choice of an 8-frame window (interval 2) from it.

Window rule: the clip that ends on frame n has the ideal frames n − 14, n − 12, …, n. Each position takes
the cached frame nearest its ideal index (ties go to the earlier frame). With every frame cached this is
exactly the official clip; after drops it uses the closest frames that exist; right after a start, seek
or reset, the positions before the first frame take the first frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN


@dataclass
class CachedFrame:
    """One frame's per-frame results.

    tokens: frame tokens from the runtime's `encode` (N, D); joints: (42, 3) float32 prepared with the
    official rules (invalid hand → −10); valid: (2,) bool hand-pose validity; views: views it was encoded with;
    t_us: its capture time (host monotonic µs).
    """

    frame_index: int
    tokens: object
    joints: np.ndarray
    valid: np.ndarray
    views: tuple[str, ...]
    t_us: int


@dataclass
class Window:
    """frames: CLIP_LENGTH cached frames, oldest first; exact: every ideal frame was cached;
    padded: some ideal frames lie before the first frame since the last reset."""

    frames: list[CachedFrame]
    exact: bool
    padded: bool


class FrameRing:
    """Holds the frames of the last SPAN frame indices. A frame index that does not increase means a seek:
    the buffer is cleared first."""

    def __init__(self) -> None:
        self._frames: dict[int, CachedFrame] = {}
        self._first: int | None = None
        self.newest: int | None = None

    def clear(self) -> None:
        self._frames.clear()
        self._first = self.newest = None

    def is_seek(self, frame_index: int) -> bool:
        return self.newest is not None and frame_index <= self.newest

    def note_index(self, frame_index: int) -> None:
        """Record that the stream reached `frame_index` (cached or not); clears on a seek, evicts old frames."""
        if self.is_seek(frame_index):
            self.clear()
        if self._first is None:
            self._first = frame_index
        self.newest = frame_index
        for old in [i for i in self._frames if i <= frame_index - SPAN]:
            del self._frames[old]

    def add(self, frame: CachedFrame) -> None:
        self.note_index(frame.frame_index)
        self._frames[frame.frame_index] = frame

    def __len__(self) -> int:
        return len(self._frames)

    def cached_indices(self) -> list[int]:
        return sorted(self._frames)

    def window(self, end: int | None = None) -> Window | None:
        """The window that ends on cached frame `end` (default: the newest), or None when nothing is cached."""
        cached = np.array([i for i in sorted(self._frames) if end is None or i <= end])
        if cached.size == 0:
            return None
        end = int(cached[-1])
        ideal = end - FRAME_INTERVAL * np.arange(CLIP_LENGTH - 1, -1, -1)
        nearest = cached[np.abs(cached[None, :] - ideal[:, None]).argmin(axis=1)]
        return Window(frames=[self._frames[int(i)] for i in nearest], exact=bool(np.all(nearest == ideal)),
                      padded=bool(ideal[0] < self._first))
