"""Replay source: an Episode as a stream of Snapshots, paced in real time (with a speed factor) or as
fast as possible, with seek, loop, a views subset and a choice of pose source, and the transport controls
of a player (pause, resume, single step, speed change, close) callable from another thread.

Pose sources: the episode's WiLoR or Rokoko stream, or "camera": the hands estimated from the ego view,
frame by frame in the iterating thread (`touchanything.devices.camera_pose`), with the frames' own
timestamps, so a replay gives the same poses every time; a frame that does not follow the previous one
(start, seek, loop) starts the estimator afresh.

Pacing keeps an absolute schedule (frame k is due at anchor + k / (fps · speed)), so a late frame is
released at once and the next ones catch up: no drift accumulates. Seek, resume and a speed change
re-anchor the schedule.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.snapshot import POSE_FROM_CAMERA, POSE_FROM_ROKOKO, POSE_FROM_WILOR, TRACKER_ROLES, VIEW_NAMES, Snapshot
from touchanything.devices.camera_pose.estimator import CameraPoseConfig, HandPoseEstimator, hands_found
from touchanything.devices.episodes.episode import Episode

POSE_SOURCES = ("wilor", "rokoko", "camera")
FILE_POSES = {"wilor": POSE_FROM_WILOR, "rokoko": POSE_FROM_ROKOKO}


@dataclass(frozen=True)
class ReplayConfig:
    """speed: real-time factor (2.0 = twice as fast), None = as fast as possible. hold_at_end: at the end
    of the episode pause (a player waiting for seek or play) instead of ending the iteration. pose_source:
    "wilor", "rokoko" (the episode's streams) or "camera" (estimated from the ego view with `camera_pose`)."""

    speed: float | None = 1.0
    loop: bool = False
    views: tuple[str, ...] = VIEW_NAMES
    pose_source: str = "wilor"
    start_frame: int = 0
    hold_at_end: bool = False
    camera_pose: CameraPoseConfig = CameraPoseConfig()


def check_config(config: ReplayConfig, episode: Episode) -> None:
    """One clear error per bad option."""
    unknown = [v for v in config.views if v not in VIEW_NAMES]
    if unknown:
        raise UserError(f"unknown view(s) {', '.join(unknown)}; choose from {', '.join(VIEW_NAMES)}")
    if config.pose_source not in POSE_SOURCES:
        raise UserError(f"unknown pose source {config.pose_source!r}; choose {', '.join(POSE_SOURCES)}")
    check_speed(config.speed)
    if not 0 <= config.start_frame < max(episode.num_frames, 1):
        raise UserError(f"start frame {config.start_frame} is outside the episode (0–{episode.num_frames - 1})")


def check_speed(speed: float | None) -> None:
    if speed is not None and not (speed > 0 and np.isfinite(speed)):
        raise UserError(f"replay speed must be a positive number, got {speed}")


class ReplaySource:
    """Iterate to get Snapshots; `seek`, `pause`, `resume`, `step`, `set_speed` and `close` may be called
    from another thread while iterating. While paused the iterator waits (a `step` releases one frame).
    With the camera pose source, making it loads the hand model (UserError when missing) and `close()`
    releases it."""

    def __init__(self, episode: Episode, config: ReplayConfig = ReplayConfig(),
                 clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep) -> None:
        check_config(config, episode)
        self.episode, self.config = episode, config
        self._clock, self._sleep = clock, sleep
        self._lock = threading.Condition()
        self._next = config.start_frame
        self._due: float | None = None
        self._period = None if config.speed is None else 1.0 / (episode.fps * config.speed)
        self._paused = False
        self._steps = 0
        self._closed = False
        self._estimator = HandPoseEstimator(config.camera_pose) if config.pose_source == "camera" else None
        self._estimator_lock = threading.Lock()
        self._estimated = -1

    @property
    def position(self) -> int:
        """The index of the next frame to be released."""
        return self._next

    @property
    def paused(self) -> bool:
        return self._paused

    def seek_target(self, frame: int) -> int:
        """The frame a seek to `frame` continues from: `frame` clamped to the episode."""
        return int(np.clip(frame, 0, max(self.episode.num_frames - 1, 0)))

    def seek(self, frame: int) -> None:
        """Continue from `seek_target(frame)`; the pacing schedule restarts there. While paused, that frame
        itself is released (a player shows the frame it was moved to), and only it: steps asked for before the
        seek are dropped."""
        with self._lock:
            self._next = self.seek_target(frame)
            self._due = None
            if self._paused:
                self._steps = 1
            self._lock.notify_all()

    def set_speed(self, speed: float | None) -> None:
        """A new real-time factor (None = as fast as possible) from the next frame on."""
        check_speed(speed)
        with self._lock:
            self._period = None if speed is None else 1.0 / (self.episode.fps * speed)
            self._due = None

    def pause(self) -> None:
        with self._lock:
            self._paused = True

    def resume(self) -> None:
        """Play on (from the start when held at the end)."""
        with self._lock:
            if self._next >= self.episode.num_frames:
                self._next = 0
            self._paused, self._steps, self._due = False, 0, None
            self._lock.notify_all()

    def step(self) -> None:
        """While paused, release exactly one more frame."""
        with self._lock:
            self._steps += 1
            self._lock.notify_all()

    def close(self) -> None:
        """End the iteration (a waiting iterator returns at once) and release the hand estimator (after the
        iterating thread's current frame)."""
        with self._lock:
            self._closed = True
            self._lock.notify_all()
        if self._estimator is not None:
            with self._estimator_lock:
                self._estimator.close()

    def _wait_while_paused(self) -> bool:
        """False when closed; consumes one step when paused."""
        while self._paused and self._steps == 0 and not self._closed:
            self._lock.wait()
        if self._paused and self._steps:
            self._steps -= 1
            self._due = None
        return not self._closed

    def _take(self) -> tuple[int, float | None] | None:
        with self._lock:
            while True:
                if not self._wait_while_paused():
                    return None
                if self._next < self.episode.num_frames:
                    break
                if self.config.loop and self.episode.num_frames:
                    self._next = 0
                    break
                if not self.config.hold_at_end or self.episode.num_frames == 0:
                    return None
                self._paused, self._steps = True, 0
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
        glove, mocap = ep.glove, ep.rokoko
        status["glove"] = "ok" if glove is not None else "absent"
        return Snapshot(
            frame_index=index, t_us=int(self._clock() * 1e6), images=images, **self._pose(index, images, status),
            pressure_raw=glove.raw[index] if glove is not None else None,
            pressure_grid=ep.pressure.grids[index] if ep.pressure is not None else None,
            imu_wxyz=glove.quat_wxyz[index] if glove is not None else None,
            trackers={role: ep.trackers.poses[index, r] for r, role in enumerate(TRACKER_ROLES)
                      if ep.trackers is not None and ep.trackers.valid[index, r]},
            source_status=status,
            glove_present=glove.present[index].copy() if glove is not None else None,
            mocap_joints=mocap.joints[index].reshape(42, 3) if mocap is not None else None,
            mocap_valid=mocap.valid[index].copy() if mocap is not None else None,
        )

    def _pose(self, index: int, images: dict[str, np.ndarray], status: dict[str, str]) -> dict:
        """The Snapshot's pose fields for frame `index` from the configured source; `status["pose"]` says
        where they come from, or why there are none."""
        none = {"joints": np.zeros((42, 3), np.float32), "joints_valid": np.zeros(2, bool)}
        if self._estimator is None:
            hands = self.episode.hands(self.config.pose_source)
            status["pose"] = self.config.pose_source if hands is not None else "absent"
            if hands is None:
                return none
            return {"joints": hands.joints[index].reshape(42, 3), "joints_valid": hands.valid[index].copy(),
                    "pose_source": FILE_POSES[self.config.pose_source]}
        if "ego" not in images:
            status["pose"] = "camera: no ego image"
            return {**none, "pose_source": POSE_FROM_CAMERA}
        with self._estimator_lock:
            if self._closed:
                status["pose"] = "camera: closed"
                return {**none, "pose_source": POSE_FROM_CAMERA}
            if index != self._estimated + 1:
                self._estimator.reset()
            self._estimated = index
            estimate = self._estimator.estimate(images["ego"], int(self.episode.timestamps_us[index]) // 1000)
        status["pose"] = f"camera: {hands_found(estimate.valid)}"
        return estimate.snapshot_fields()
