"""Replay source: an Episode as a stream of Snapshots, paced in real time (with a speed factor) or as
fast as possible, with seek, loop, a views subset and a choice of pose source.

Pacing keeps an absolute schedule (frame k is due at anchor + k / (fps · speed)), so a late frame is
released at once and the next ones catch up: no drift accumulates. Seek re-anchors the schedule.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from devices.episode import Episode
from devices.errors import UserError
from devices.snapshot import TRACKER_ROLES, VIEW_NAMES, Snapshot

POSE_SOURCES = ("wilor", "rokoko")


@dataclass(frozen=True)
class ReplayConfig:
    """speed: real-time factor (2.0 = twice as fast), None = as fast as possible."""

    speed: float | None = 1.0
    loop: bool = False
    views: tuple[str, ...] = VIEW_NAMES
    pose_source: str = "wilor"
    start_frame: int = 0


def check_config(config: ReplayConfig, episode: Episode) -> None:
    """One clear error per bad option."""
    unknown = [v for v in config.views if v not in VIEW_NAMES]
    if unknown:
        raise UserError(f"unknown view(s) {', '.join(unknown)}; choose from {', '.join(VIEW_NAMES)}")
    if config.pose_source not in POSE_SOURCES:
        raise UserError(f"unknown pose source {config.pose_source!r}; choose wilor or rokoko")
    if config.speed is not None and not (config.speed > 0 and np.isfinite(config.speed)):
        raise UserError(f"replay speed must be a positive number, got {config.speed}")
    if not 0 <= config.start_frame < max(episode.num_frames, 1):
        raise UserError(f"start frame {config.start_frame} is outside the episode (0–{episode.num_frames - 1})")


class ReplaySource:
    """Iterate to get Snapshots; `seek` may be called from another thread while iterating."""

    def __init__(self, episode: Episode, config: ReplayConfig = ReplayConfig(),
                 clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep) -> None:
        check_config(config, episode)
        self.episode, self.config = episode, config
        self._clock, self._sleep = clock, sleep
        self._lock = threading.Lock()
        self._next = config.start_frame
        self._due: float | None = None
        self._period = None if config.speed is None else 1.0 / (episode.fps * config.speed)

    def seek(self, frame: int) -> None:
        """Continue from `frame` (clamped to the episode); the pacing schedule restarts there."""
        with self._lock:
            self._next = int(np.clip(frame, 0, max(self.episode.num_frames - 1, 0)))
            self._due = None

    def _take(self) -> tuple[int, float | None] | None:
        with self._lock:
            if self._next >= self.episode.num_frames:
                if not self.config.loop or self.episode.num_frames == 0:
                    return None
                self._next = 0
            index = self._next
            self._next += 1
            if self._period is None:
                return index, None
            self._due = self._clock() if self._due is None else self._due + self._period
            return index, self._due

    def __iter__(self) -> Iterator[Snapshot]:
        while (taken := self._take()) is not None:
            index, due = taken
            snapshot = self.snapshot(index)
            if due is not None and (delay := due - self._clock()) > 0:
                self._sleep(delay)
            snapshot.t_us = int(self._clock() * 1e6)
            yield snapshot

    def snapshot(self, index: int) -> Snapshot:
        """Frame `index` of the episode as a Snapshot (t_us = now on the monotonic clock)."""
        ep, status = self.episode, {}
        images = {}
        for view in self.config.views:
            source = ep.views.get(view)
            image = source.read(index) if source is not None else None
            status[view] = "ok" if image is not None else ("absent" if source is None else "no frame")
            if image is not None:
                images[view] = image
        hands = ep.hands(self.config.pose_source)
        status["pose"] = self.config.pose_source if hands is not None else "absent"
        joints = hands.joints[index].reshape(42, 3) if hands else np.zeros((42, 3), np.float32)
        valid = hands.valid[index].copy() if hands else np.zeros(2, bool)
        glove = ep.glove
        status["glove"] = "ok" if glove is not None else "absent"
        return Snapshot(
            frame_index=index, t_us=int(self._clock() * 1e6), images=images, joints=joints, joints_valid=valid,
            pressure_raw=glove.raw[index] if glove is not None else None,
            pressure_grid=ep.pressure.grids[index] if ep.pressure is not None else None,
            imu_wxyz=glove.quat_wxyz[index] if glove is not None else None,
            trackers={role: ep.trackers.poses[index, r] for r, role in enumerate(TRACKER_ROLES)
                      if ep.trackers is not None and ep.trackers.valid[index, r]},
            source_status=status,
        )
