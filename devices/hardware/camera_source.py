"""The common shape of camera sources: a reading (RGB image, host capture time, sequence number) in a
latest-value slot, with frames lost before the slot counted from gaps in the sequence numbers, and the
format the device actually negotiated beside the one the scene asked for.

A camera that goes away is reopened by the shared reader (`ThreadedSource`, `DeviceLost`); its sequence
numbers go on increasing across the reopen (the first frame after it is one more than the last before),
and `silent_s()` (time since the last frame, or since the open) lets a live camera notice a device that
stopped delivering."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.core.errors import DeviceNotConnectedError
from touchanything.devices.hardware.threaded_source import (
    DEFAULT_BACKOFF_S,
    SourceCounters,
    ThreadedSource,
    now_us,
)


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


@dataclass(frozen=True)
class CameraFormat:
    """A frame size in pixels and a frame rate (None: the device does not say)."""

    width: int
    height: int
    fps: float | None = None

    def __str__(self) -> str:
        rate = f" at {self.fps:g} fps" if self.fps else ""
        return f"{self.width}×{self.height}{rate}"

    def differs_from(self, other: CameraFormat) -> bool:
        """True when the size differs, or both rates are known and differ by more than 0.5 fps."""
        size = (self.width, self.height) != (other.width, other.height)
        return size or (self.fps is not None and other.fps is not None and abs(self.fps - other.fps) > 0.5)


class CameraSource(ThreadedSource[CameraReading]):
    """A ThreadedSource of CameraReadings; subclasses call `_publish_frame` from `_step` and set
    `_negotiated` (at open, or from the first frame) so `negotiated` and the status can report it.

    requested: the format the scene asks for (None: whatever the source gives, e.g. a replay pipeline).
    resizes: frames of another size are resized to the requested size (else delivered as they come).
    reconnect_backoff_s: (first, longest) wait between attempts to reopen a camera that went away.
    """

    def __init__(self, name: str, requested: CameraFormat | None = None, resizes: bool = False,
                 reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S) -> None:
        super().__init__(name, reconnect_backoff_s)
        self.requested = requested
        self._resizes = resizes
        self._negotiated: CameraFormat | None = None
        self._last_sequence: int | None = None
        self._sequence_base = 0
        self._rebase = False
        self._heard_us = 0
        self._frames_since_open = 0

    def _new_counters(self) -> CameraCounters:
        return CameraCounters()

    @property
    def counters(self) -> CameraCounters:
        return super().counters  # type: ignore[return-value]

    @property
    def negotiated(self) -> CameraFormat | None:
        """The size and rate the device actually delivers (None until known, e.g. before the first frame of
        a depthai queue); DeviceNotConnectedError when not connected."""
        if not self.is_connected:
            raise DeviceNotConnectedError(f"{self.name} is not connected; connect it to see what it negotiated")
        return self._negotiated

    def connect(self) -> None:
        self._last_sequence, self._negotiated = None, None
        self._sequence_base, self._rebase = 0, False
        self._heard_us, self._frames_since_open = now_us(), 0
        super().connect()

    def _reopen(self) -> None:
        """Open the camera again; its numbering restarts, so the next frame is rebased to follow the last."""
        self._rebase = self._last_sequence is not None
        self._heard_us, self._frames_since_open = now_us(), 0
        self._open()

    def silent_s(self) -> float:
        """Seconds since the last frame, or since the (re)open before the first."""
        return (now_us() - self._heard_us) / 1e6

    @property
    def frames_since_open(self) -> int:
        """Frames published since the last (re)open."""
        return self._frames_since_open

    def _status_details(self) -> str:
        """", negotiated 1280×720 at 15 fps (asked 640×480 at 30 fps; frames resized to 640×480)" when the
        device delivers something other than what the scene asked for."""
        requested, negotiated = self.requested, self._negotiated
        if requested is None or negotiated is None or not negotiated.differs_from(requested):
            return ""
        size_differs = (negotiated.width, negotiated.height) != (requested.width, requested.height)
        action = f"; frames resized to {requested.width}×{requested.height}" if self._resizes and size_differs else ""
        return f", negotiated {negotiated} (asked {requested}{action})"

    def _publish_frame(self, image: np.ndarray, t_us: int, sequence: int) -> None:
        """Publish one (H, W, 3) uint8 RGB frame; a jump in `sequence` counts the frames skipped."""
        if self._rebase:  # the first frame after a reopen follows the last frame before it
            self._sequence_base, self._rebase = self._last_sequence + 1 - sequence, False
        sequence += self._sequence_base
        self._heard_us, self._frames_since_open = now_us(), self._frames_since_open + 1
        skipped = 0
        if self._last_sequence is not None and sequence > self._last_sequence + 1:
            skipped = sequence - self._last_sequence - 1
        self._last_sequence = sequence
        self._publish(CameraReading(image, t_us, sequence), t_us, dropped=skipped)
