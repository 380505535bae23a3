"""Hands from the ego camera, live: a source on the one device contract that estimates the hands in the
camera's newest frame, latest wins.

Its reader thread waits for a frame newer than the last one it estimated (the camera's latest-value slot),
estimates the hands in it (`touchanything.devices.camera_pose`, VIDEO mode with the frames' capture times)
and publishes a `CameraHandsReading` carrying that very frame, so the rig shows and models the image the
pose belongs to. Frames that arrive while it works are skipped (counted in `skipped`): like the live engine
it always works on the newest frame and never builds a backlog. The scene's `[hands]` with
`source = "camera"` makes one (the registry gives it the scene's ego camera). A missing or wrong hand-model
file is a UserError at connect.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from touchanything.devices.camera_pose.estimator import CameraPoseConfig, HandEstimate, HandPoseEstimator, hands_found
from touchanything.devices.hardware.camera_source import CameraReading
from touchanything.devices.hardware.threaded_source import SourceCounters, ThreadedSource

POLL_S = 0.002
"""How often the reader looks for a new camera frame while it waits (at most ~0.1 s per step)."""
STEP_WAIT_S = 0.1


@dataclass(frozen=True)
class CameraHandsReading:
    """image: the (H, W, 3) uint8 RGB frame the hands were estimated in; t_us: its capture time; estimate:
    the hands found in it."""

    image: np.ndarray
    t_us: int
    estimate: HandEstimate


@dataclass
class CameraHandsCounters(SourceCounters):
    """skipped: camera frames that came and went while the estimator was busy (or that the camera dropped)."""

    skipped: int = 0


class CameraHands(ThreadedSource[CameraHandsReading]):
    """Follows `camera` (any source of CameraReadings, connected before this one)."""

    def __init__(self, config: CameraPoseConfig, camera: ThreadedSource[CameraReading]) -> None:
        super().__init__(f"camera hands ({camera.name})")
        self.config = config
        self.camera = camera
        self._estimator: HandPoseEstimator | None = None
        self._last_sequence: int | None = None
        self._found = ""

    def _new_counters(self) -> CameraHandsCounters:
        return CameraHandsCounters()

    @property
    def counters(self) -> CameraHandsCounters:
        return super().counters  # type: ignore[return-value]

    def _open(self) -> None:
        self._estimator = HandPoseEstimator(self.config)
        self._last_sequence, self._found = None, ""

    def _close(self) -> None:
        if self._estimator is not None:
            self._estimator.close()
            self._estimator = None

    def _status_details(self) -> str:
        return f", {self._found}" if self._found else ""

    def _next_frame(self) -> CameraReading | None:
        """The camera's newest frame when it is newer than the last one estimated, waiting up to STEP_WAIT_S."""
        for _ in range(round(STEP_WAIT_S / POLL_S)):
            reading = self.camera.latest()
            if reading is not None and (self._last_sequence is None or reading.sequence > self._last_sequence):
                return reading
            if self._stop.wait(POLL_S):
                return None
        return None

    def _step(self) -> None:
        reading = self._next_frame()
        if reading is None:
            return
        skipped = 0 if self._last_sequence is None else max(reading.sequence - self._last_sequence - 1, 0)
        self._last_sequence = reading.sequence
        estimate = self._estimator.estimate(reading.image, reading.t_us // 1000)
        self._found = hands_found(estimate.valid)
        self._publish(CameraHandsReading(reading.image, reading.t_us, estimate), reading.t_us, skipped=skipped)
