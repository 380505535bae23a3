"""Luxonis OAK cameras through depthai 3.x: one camera socket as a live RGB CameraSource.

`DepthaiFrameSource` turns the ImgFrames of any depthai output queue into CameraReadings (RGB image,
host monotonic capture time, sequence number); `OakCamera` opens a device and builds the camera pipeline
that feeds it. The split lets a host-only pipeline (ReplayVideo) drive the very same frame path.

Negotiated format: the first frame says what the device delivers (`ImgFrame.getWidth/getHeight/getFps`);
it becomes `negotiated`, and the status says so when it differs from the scene's request (frames are
delivered as they come, not resized).

Timestamps: `ImgFrame.getTimestamp()` is the capture time already synchronised to the host clock that
`dai.Clock.now()` reads, std::chrono::steady_clock (CLOCK_MONOTONIC on Linux, the clock behind
Python's time.monotonic, so the offset measured at connect is ~0 µs there). The offset is measured
rather than assumed so that other operating systems, whose Python monotonic clock may differ, get it right.

Device gone (a `live` source: the OAK): its output queue closes (the device dropped off the bus, the
pipeline died) or no frame came for `frame_timeout_s` (`FIRST_FRAME_TIMEOUT_S` after a (re)open, while the
device boots the pipeline). The shared reader then closes it and reopens it by its device id (the one
configured, else the one first opened) with back-off, counting `reconnects`. A host-only replay that ends
is a normal end (`SourceEnded`).
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta

import cv2

os.environ.setdefault("DEPTHAI_LEVEL", "error")  # else importing depthai logs "USB protocol not available"
import depthai as dai  # noqa: E402
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

SEARCH_TIMEOUT_MS = "2000"
"""Default DEPTHAI_SEARCH_TIMEOUT: opening a listed device that then vanished fails in ~2 s, not ~11 s."""
QUEUE_SIZE = 4
GET_TIMEOUT = timedelta(milliseconds=100)
CLOCK_PROBES = 5
FIRST_FRAME_TIMEOUT_S = 10.0
"""Longest wait for the first frame after a (re)open before a live device counts as gone."""
ONE_US = timedelta(microseconds=1)

PipelineBuilder = Callable[[], tuple[dai.Pipeline, dai.MessageQueue]]


@dataclass(frozen=True)
class OakCameraConfig:
    """device_id: DeviceID (MxID), IP address or USB port name; None = the first OAK found.
    socket: camera board socket name (CAM_A = the colour camera). Output size in pixels, rate in Hz.
    frame_timeout_s: a camera silent this long is gone (reopened); reconnect_backoff_s: (first, longest)
    wait between attempts to reopen it."""

    device_id: str | None = None
    socket: str = "CAM_A"
    width: int = 640
    height: int = 480
    fps: float = 30
    frame_timeout_s: float = 2.0
    reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S

    def __post_init__(self) -> None:
        object.__setattr__(self, "reconnect_backoff_s", check_backoff(self.reconnect_backoff_s, "OAK camera"))
        if not (math.isfinite(self.frame_timeout_s) and self.frame_timeout_s > 0):
            raise UserError(f"OAK camera frame timeout must be a positive number of seconds, got {self.frame_timeout_s}")
        if self.socket not in dai.CameraBoardSocket.__members__:
            choices = ", ".join(name for name in dai.CameraBoardSocket.__members__ if name.startswith("CAM_"))
            raise UserError(f"unknown OAK camera socket {self.socket!r}; choose one of {choices}")
        if self.width <= 0 or self.height <= 0:
            raise UserError(f"OAK camera size must be positive, got {self.width}×{self.height}")
        if not (math.isfinite(self.fps) and self.fps > 0):
            raise UserError(f"OAK camera fps must be a positive number, got {self.fps}")


def host_clock_offset_us() -> int:
    """µs to add to a `dai.Clock` time to get `time.monotonic` time; from the tightest of a few probes."""
    probes = []
    for _ in range(CLOCK_PROBES):
        before = now_us()
        clock_us = dai.Clock.now() // ONE_US
        after = now_us()
        probes.append((after - before, (before + after) // 2 - clock_us))
    return min(probes)[1]


def frame_rgb(frame: dai.ImgFrame) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an ImgFrame; RGB888i is used as is, other types go through OpenCV."""
    if frame.getType() == dai.ImgFrame.Type.RGB888i:
        return frame.getFrame()
    image = frame.getCvFrame()
    return cv2.cvtColor(image, cv2.COLOR_GRAY2RGB if image.ndim == 2 else cv2.COLOR_BGR2RGB)


def frame_format(frame: dai.ImgFrame) -> CameraFormat:
    """The size and rate an ImgFrame reports (rate None when it reports none)."""
    fps = frame.getFps()
    return CameraFormat(frame.getWidth(), frame.getHeight(), fps if math.isfinite(fps) and fps > 0 else None)


class DepthaiFrameSource(CameraSource):
    """The frames of one depthai output queue as a CameraSource. `build` creates the pipeline (not yet
    started) and the queue; connect starts the pipeline, disconnect stops it. `requested`: the format
    asked of the pipeline, compared with the first frame's. `live`: the queue belongs to a device, so its
    closing or `frame_timeout_s` without a frame means the device is gone (reopened through `build` with
    back-off) rather than the end of the stream."""

    def __init__(self, name: str, build: PipelineBuilder, requested: CameraFormat | None = None, live: bool = False,
                 frame_timeout_s: float = 2.0, reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S) -> None:
        super().__init__(name, requested, reconnect_backoff_s=reconnect_backoff_s)
        self._build = build
        self._live = live
        self._frame_timeout_s = frame_timeout_s
        self._pipeline: dai.Pipeline | None = None
        self._queue: dai.MessageQueue | None = None
        self._offset_us = 0

    def _open(self) -> None:
        self._pipeline, self._queue = self._build()
        self._offset_us = host_clock_offset_us()
        self._pipeline.start()

    def _step(self) -> None:
        try:
            frame = self._queue.get(GET_TIMEOUT)
        except dai.MessageQueue.QueueException:
            if self._live:
                raise DeviceLost(f"{self.name}: the depthai pipeline stopped") from None
            raise SourceEnded("the depthai pipeline stopped") from None
        if frame is None and self._live:
            limit = self._frame_timeout_s if self.frames_since_open else max(self._frame_timeout_s, FIRST_FRAME_TIMEOUT_S)
            if (silent_s := self.silent_s()) > limit:
                raise DeviceLost(f"{self.name}: no frame for {silent_s:.1f} s")
        if frame is not None:
            if self._negotiated is None:
                self._negotiated = frame_format(frame)
            t_us = frame.getTimestamp() // ONE_US + self._offset_us
            self._publish_frame(frame_rgb(frame), t_us, frame.getSequenceNum())

    def _close(self) -> None:
        pipeline, self._pipeline, self._queue = self._pipeline, None, None
        if pipeline is not None:  # (stopping the pipeline of a vanished device may raise; it is dropped anyway)
            pipeline.stop()
            pipeline.wait()


class OakCamera(DepthaiFrameSource):
    """One OAK camera socket at the configured size and rate, RGB."""

    def __init__(self, config: OakCameraConfig = OakCameraConfig()) -> None:
        super().__init__(f"OAK {config.device_id or 'camera'} {config.socket}", self._build_camera,
                         CameraFormat(config.width, config.height, config.fps), live=True,
                         frame_timeout_s=config.frame_timeout_s, reconnect_backoff_s=config.reconnect_backoff_s)
        self.config = config
        self._device: dai.Device | None = None
        self._device_id = config.device_id

    def connect(self) -> None:
        self._device_id = self.config.device_id
        super().connect()

    def _build_camera(self) -> tuple[dai.Pipeline, dai.MessageQueue]:
        self._device = open_device(self._device_id)
        self._device_id = self._device_id or self._device.getDeviceId()  # reopened by the id first opened
        config = self.config
        try:
            pipeline = dai.Pipeline(self._device)
            camera = pipeline.create(dai.node.Camera).build(dai.CameraBoardSocket.__members__[config.socket])
            output = camera.requestOutput((config.width, config.height), type=dai.ImgFrame.Type.RGB888i,
                                          fps=config.fps)
            return pipeline, output.createOutputQueue(maxSize=QUEUE_SIZE, blocking=False)
        except RuntimeError as exc:
            raise UserError(f"OAK camera {self._device.getDeviceId()}: cannot stream {config.socket} at "
                            f"{config.width}×{config.height} {config.fps:g} fps ({exc})") from None

    def _close(self) -> None:
        try:
            super()._close()
        finally:
            device, self._device = self._device, None
            if device is not None:
                device.close()


def open_device(device_id: str | None) -> dai.Device:
    """Open the OAK named by DeviceID, IP or USB port name (None: the first one); UserError when absent."""
    os.environ.setdefault("DEPTHAI_SEARCH_TIMEOUT", SEARCH_TIMEOUT_MS)
    available = dai.Device.getAllAvailableDevices()
    names = [info.getDeviceId() for info in available]
    wanted = device_id or "any"
    if not available or (device_id is not None and device_id not in names + [info.name for info in available]):
        raise UserError(f"no OAK camera found (device id {wanted}); connected: {', '.join(names) or 'none'}")
    try:
        return dai.Device(dai.DeviceInfo(device_id)) if device_id else dai.Device()
    except RuntimeError as exc:
        raise UserError(f"cannot open OAK camera {wanted} ({exc}); is another program using it?") from None
