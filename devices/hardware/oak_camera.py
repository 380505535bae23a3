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

from touchanything.devices.errors import UserError
from touchanything.devices.hardware.camera_source import CameraFormat, CameraSource
from touchanything.devices.hardware.threaded_source import SourceEnded, now_us

SEARCH_TIMEOUT_MS = "2000"
"""Default DEPTHAI_SEARCH_TIMEOUT: opening a listed device that then vanished fails in ~2 s, not ~11 s."""
QUEUE_SIZE = 4
GET_TIMEOUT = timedelta(milliseconds=100)
CLOCK_PROBES = 5
ONE_US = timedelta(microseconds=1)

PipelineBuilder = Callable[[], tuple[dai.Pipeline, dai.MessageQueue]]


@dataclass(frozen=True)
class OakCameraConfig:
    """device_id: DeviceID (MxID), IP address or USB port name; None = the first OAK found.
    socket: camera board socket name (CAM_A = the colour camera). Output size in pixels, rate in Hz."""

    device_id: str | None = None
    socket: str = "CAM_A"
    width: int = 640
    height: int = 480
    fps: float = 30

    def __post_init__(self) -> None:
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
    asked of the pipeline, compared with the first frame's."""

    def __init__(self, name: str, build: PipelineBuilder, requested: CameraFormat | None = None) -> None:
        super().__init__(name, requested)
        self._build = build
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
            raise SourceEnded("the depthai pipeline stopped") from None
        if frame is not None:
            if self._negotiated is None:
                self._negotiated = frame_format(frame)
            t_us = frame.getTimestamp() // ONE_US + self._offset_us
            self._publish_frame(frame_rgb(frame), t_us, frame.getSequenceNum())

    def _close(self) -> None:
        if self._pipeline is not None:
            self._pipeline.stop()
            self._pipeline.wait()
        self._pipeline = self._queue = None


class OakCamera(DepthaiFrameSource):
    """One OAK camera socket at the configured size and rate, RGB."""

    def __init__(self, config: OakCameraConfig = OakCameraConfig()) -> None:
        super().__init__(f"OAK {config.device_id or 'camera'} {config.socket}", self._build_camera,
                         CameraFormat(config.width, config.height, config.fps))
        self.config = config
        self._device: dai.Device | None = None

    def _build_camera(self) -> tuple[dai.Pipeline, dai.MessageQueue]:
        self._device = open_device(self.config.device_id)
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
        super()._close()
        if self._device is not None:
            self._device.close()
        self._device = None


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
