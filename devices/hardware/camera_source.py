"""The common shape of camera sources: a reading (RGB image, host capture time, sequence number) in a
latest-value slot, with frames lost before the slot counted from gaps in the sequence numbers."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.devices.hardware.threaded_source import SourceCounters, ThreadedSource


@dataclass(frozen=True)
class CameraReading:
    """image: (H, W, 3) uint8 RGB; t_us: capture time on the host monotonic clock in µs;
    sequence: frame number from the source, increasing (a gap means frames were dropped)."""

    image: np.ndarray
    t_us: int
    sequence: int


@dataclass
class CameraCounters(SourceCounters):
    """dropped: frames the source skipped before the slot (gaps in `sequence`, e.g. a full device queue,
    or a paced file catching up with its schedule)."""

    dropped: int = 0


class CameraSource(ThreadedSource[CameraReading]):
    """A ThreadedSource of CameraReadings; subclasses call `_publish_frame` from `_step`."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._last_sequence: int | None = None

    def _new_counters(self) -> CameraCounters:
        return CameraCounters()

    @property
    def counters(self) -> CameraCounters:
        return super().counters  # type: ignore[return-value]

    def connect(self) -> None:
        self._last_sequence = None
        super().connect()

    def _publish_frame(self, image: np.ndarray, t_us: int, sequence: int) -> None:
        """Publish one (H, W, 3) uint8 RGB frame; a jump in `sequence` counts the frames skipped."""
        if self._last_sequence is not None and sequence > self._last_sequence + 1:
            with self._lock:
                self._counters.dropped += sequence - self._last_sequence - 1
        self._last_sequence = sequence
        self._publish(CameraReading(image, t_us, sequence), t_us)
