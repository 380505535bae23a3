"""Generic cameras through OpenCV: a UVC device (index or /dev/video* path) or a video file, as a CameraSource.

A video file behaves like a live camera: frame k is released at anchor + k / fps (the file's own fps,
the configured one when the file has none), on an absolute schedule that does not drift; a reader that
falls behind skips the overdue frames (counted as dropped) instead of building up lag. With `loop`,
the file starts over when it ends and the sequence numbers keep increasing.

Frames come out as (height, width, 3) uint8 RGB at the configured size; a source that delivers another
size is resized (INTER_AREA). What the device (or file) actually gives is read back after opening
(CAP_PROP_FRAME_WIDTH / HEIGHT / FPS) as `negotiated`, and the status says so when it differs from the
request. A live frame's `t_us` is the host time when OpenCV handed it over.

Device gone (the reader closes the capture and reopens it by the same name with back-off, counting
`reconnects`): a source path (a `/dev/v4l/by-id/…` link, a device node, a video file) that no longer
exists, or a live camera that delivered no frame for `frame_timeout_s`. A device path is resolved again
on every reopen, so a camera that comes back as another `/dev/video*` is found. A video file that simply
ends (without `loop`) is a normal end (`SourceEnded`), not a lost device.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from touchanything.core.errors import UserError
from touchanything.devices.hardware.camera_source import CameraFormat, CameraSource
from touchanything.devices.hardware.threaded_source import (
    DEFAULT_BACKOFF_S,
    DeviceLost,
    SourceEnded,
    check_backoff,
    now_us,
)
from touchanything.devices.quiet_stderr import quiet_opencv

MAX_CATCH_UP_S = 1.0
"""A file reader further behind its schedule than this (a suspended machine) restarts the schedule
at the current frame instead of skipping frames to catch up."""


@dataclass(frozen=True)
class OpenCVCameraConfig:
    """source: camera index, device path (/dev/video*, /dev/v4l/by-id/…) or video file path. Size in pixels;
    fps: the rate asked of a camera, and the pace of a file that states none. loop: start a file over at its
    end. frame_timeout_s: a live camera silent this long is gone (reopened). reconnect_backoff_s: (first,
    longest) wait between attempts to reopen a camera that went away."""

    source: int | str
    width: int = 640
    height: int = 480
    fps: float = 30
    loop: bool = False
    frame_timeout_s: float = 2.0
    reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S

    def __post_init__(self) -> None:
        object.__setattr__(self, "reconnect_backoff_s", check_backoff(self.reconnect_backoff_s, "camera"))
        if not (math.isfinite(self.frame_timeout_s) and self.frame_timeout_s > 0):
            raise UserError(f"camera frame timeout must be a positive number of seconds, got {self.frame_timeout_s}")
        if self.width <= 0 or self.height <= 0:
            raise UserError(f"camera size must be positive, got {self.width}×{self.height}")
        if not (math.isfinite(self.fps) and self.fps > 0):
            raise UserError(f"camera fps must be a positive number, got {self.fps}")

    @property
    def is_file(self) -> bool:
        return isinstance(self.source, str) and not self.source.startswith("/dev/")

    @property
    def format(self) -> CameraFormat:
        """The size and rate asked for."""
        return CameraFormat(self.width, self.height, self.fps)


def negotiated_format(capture: cv2.VideoCapture) -> CameraFormat:
    """What an opened capture delivers, read back from OpenCV: size, and fps (None when it reports none)."""
    fps = capture.get(cv2.CAP_PROP_FPS)
    return CameraFormat(round(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), round(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)),
                        fps if math.isfinite(fps) and fps > 0 else None)


def request_format(capture: cv2.VideoCapture, wanted: CameraFormat) -> CameraFormat:
    """Ask an opened camera for `wanted` and return what it negotiated (drivers pick the nearest they have)."""
    capture.set(cv2.CAP_PROP_FRAME_WIDTH, wanted.width)
    capture.set(cv2.CAP_PROP_FRAME_HEIGHT, wanted.height)
    if wanted.fps:
        capture.set(cv2.CAP_PROP_FPS, wanted.fps)
    return negotiated_format(capture)


def fit_rgb(bgr: np.ndarray, width: int, height: int) -> np.ndarray:
    """OpenCV's (h, w, 3) BGR frame as (height, width, 3) uint8 RGB."""
    if bgr.shape[:2] != (height, width):
        bgr = cv2.resize(bgr, (width, height), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


class OpenCVCamera(CameraSource):
    """A UVC camera or a video file paced like one. `negotiated` is what the device (or file) gives."""

    def __init__(self, config: OpenCVCameraConfig) -> None:
        super().__init__(f"OpenCV camera {config.source}", config.format, resizes=True,
                         reconnect_backoff_s=config.reconnect_backoff_s)
        self.config = config
        self._capture: cv2.VideoCapture | None = None
        self._period_s = 1.0 / config.fps
        self._anchor_s = 0.0
        self._next = 0
        self._frames_this_pass = 0

    def _open(self) -> None:
        """Open the source; OpenCV's own warnings are kept quiet (a failure is this adapter's one message)."""
        with quiet_opencv():
            if self.config.is_file:
                self._open_file(Path(self.config.source))
            else:
                self._open_camera()
        self._next = self._frames_this_pass = 0
        self._anchor_s = now_us() / 1e6

    def _open_file(self, path: Path) -> None:
        if not path.is_file():
            raise UserError(f"video file {path} not found")
        self._capture = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG)
        if not self._capture.isOpened():
            raise UserError(f"video file {path} cannot be read (not a video OpenCV can decode)")
        self._negotiated = negotiated_format(self._capture)
        self._period_s = 1.0 / (self._negotiated.fps or self.config.fps)

    def _open_camera(self) -> None:
        source = self.config.source
        self._capture = cv2.VideoCapture(os.path.realpath(source) if isinstance(source, str) else source)
        if not self._capture.isOpened():
            raise UserError(f"no camera at {source!r} (OpenCV cannot open it); check that it is plugged in "
                            f"and not used by another program")
        self._negotiated = request_format(self._capture, self.config.format)

    def _step(self) -> None:
        if self.config.is_file:
            self._step_file()
            return
        ok, bgr = self._capture.read()
        if not ok:
            self._check_present()
            if (silent_s := self.silent_s()) > self.config.frame_timeout_s:
                raise DeviceLost(f"no frame from {self.config.source} for {silent_s:.1f} s")
            raise OSError(f"camera {self.config.source!r} delivered no frame")
        if self._next == 0:  # the first frame is the truth where a backend reads back no size
            self._negotiated = CameraFormat(bgr.shape[1], bgr.shape[0], self._negotiated.fps)
        self._publish_frame(fit_rgb(bgr, self.config.width, self.config.height), now_us(), self._next)
        self._next += 1

    def _step_file(self) -> None:
        delay = self._anchor_s + self._next * self._period_s - now_us() / 1e6
        if delay > 0:
            self._stop.wait(delay)
            return
        self._check_present()
        overdue = int(-delay / self._period_s)
        if overdue * self._period_s > MAX_CATCH_UP_S:
            self._anchor_s -= delay
            overdue = 0
        for _ in range(overdue):
            self._file_frame(decode=False)
        bgr = self._file_frame(decode=True)
        self._publish_frame(fit_rgb(bgr, self.config.width, self.config.height), now_us(), self._next - 1)

    def _check_present(self) -> None:
        """DeviceLost when the source is a path that no longer exists (an unplugged camera's by-id link)."""
        if isinstance(self.config.source, str) and not os.path.exists(self.config.source):
            raise DeviceLost(f"{self.config.source} vanished")

    def _file_frame(self, decode: bool) -> np.ndarray | None:
        """Move one frame on in the file (decoded when asked, else only grabbed) and on the schedule;
        at the end of the file, start over when looping, else raise SourceEnded."""
        for attempt in range(2):
            ok, bgr = self._capture.read() if decode else (self._capture.grab(), None)
            if ok:
                self._frames_this_pass += 1
                self._next += 1
                return bgr
            if attempt or not self.config.loop or self._frames_this_pass == 0:
                break
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            self._frames_this_pass = 0
        raise SourceEnded(f"end of {self.config.source} after {self._next} frames")

    def _close(self) -> None:
        if self._capture is not None:
            self._capture.release()
        self._capture = None
