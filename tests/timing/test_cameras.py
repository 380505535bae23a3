"""Camera sources: the reader-thread base, a host-only depthai pipeline (ReplayVideo) through the OAK frame
path, OpenCV on real video files, and the user errors of absent devices and files."""
from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import depthai as dai
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from touchanything.core.errors import DeviceAlreadyConnectedError, DeviceNotConnectedError, UserError
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.hardware.camera_source import CameraFormat, CameraSource
from touchanything.devices.hardware.oak_camera import DepthaiFrameSource, OakCamera, OakCameraConfig, host_clock_offset_us
from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
from touchanything.devices.hardware.threaded_source import DeviceLost, LatestSlot, SourceEnded, now_us

RED, GREEN, BLUE_STEP = 200, 50, 8


def wait_for(predicate: Callable[[], object], timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "condition not met before the deadline"
        time.sleep(0.005)


def reader_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name.endswith(" reader")]


def write_video(path: Path, frames: int, fps: int = 30, size: tuple[int, int] = (48, 64)) -> Path:
    """Solid frames: red 200, green 50, blue = 8 × frame index (so a frame names itself)."""
    with VideoWriter(path, fps=fps, crf=0) as writer:
        for i in range(frames):
            image = np.empty((*size, 3), np.uint8)
            image[...] = (RED, GREEN, BLUE_STEP * i)
            writer.write(image)
    return path


def assert_frame(image: np.ndarray, index: int, size: tuple[int, int]) -> None:
    assert image.shape == (*size, 3) and image.dtype == np.uint8
    r, g, b = image.reshape(-1, 3).mean(axis=0)
    assert abs(r - RED) < 8 and abs(g - GREEN) < 8 and abs(b - BLUE_STEP * index) < 8, (r, g, b, index)


# --- the reader-thread base --------------------------------------------------------------------------


class ScriptedCamera(CameraSource):
    """A CameraSource whose steps follow a script: a sequence number to publish, an exception to raise."""

    def __init__(self, script: list[int | Exception], fail_open: bool = False) -> None:
        super().__init__("scripted")
        self.script, self.fail_open, self.closed = list(script), fail_open, 0

    def _open(self) -> None:
        if self.fail_open:
            raise UserError("scripted camera is absent")

    def _step(self) -> None:
        if not self.script:
            raise SourceEnded("script done")
        item = self.script.pop(0)
        if isinstance(item, Exception):
            raise item
        self._publish_frame(np.zeros((2, 2, 3), np.uint8), now_us(), item)

    def _close(self) -> None:
        self.closed += 1


def test_sequence_gaps_count_as_dropped_and_a_failing_step_is_counted_not_fatal():
    camera = ScriptedCamera([0, 1, 5, RuntimeError("bad frame"), 6, 9])
    with camera:
        wait_for(lambda: camera.ended)
        counts = camera.counters
        assert (counts.samples, counts.dropped, counts.errors) == (5, 5, 1)
        assert counts.unread == 4  # nobody read: every frame but the last was replaced unread
        assert camera.latest().sequence == 9
        status = camera.status()
        assert status.startswith("stopped (script done)") and "5 dropped" in status
        assert "last error: RuntimeError: bad frame" in status
    assert camera.status() == "disconnected" and camera.closed == 1 and not reader_threads()


def test_failed_connect_closes_and_leaves_no_thread_and_double_connect_is_refused():
    camera = ScriptedCamera([], fail_open=True)
    with pytest.raises(UserError, match="absent"):
        camera.connect()
    assert camera.closed == 1 and not camera.is_connected and not reader_threads()
    camera = ScriptedCamera([0])
    with camera:
        with pytest.raises(DeviceAlreadyConnectedError, match="^scripted is already connected; disconnect it first$"):
            camera.connect()
    camera.disconnect()  # a second disconnect does nothing
    assert camera.closed == 1


class FlakyCamera(CameraSource):
    """A CameraSource whose device goes away after `before` frames (DeviceLost) and refuses `refusals`
    reopens before it returns, numbering its frames from 0 again."""

    def __init__(self, before: int, refusals: int) -> None:
        super().__init__("flaky", reconnect_backoff_s=(0.05, 0.2))
        self.before, self.refusals, self.next, self.opens, self.closed = before, refusals, 0, [], 0

    def _open(self) -> None:
        self.opens.append(time.monotonic())
        if len(self.opens) > 1 and self.refusals:
            self.refusals -= 1
            raise UserError("flaky camera is not there")
        self.next = 0

    def _step(self) -> None:
        if len(self.opens) == 1 and self.next == self.before:
            raise DeviceLost("flaky camera vanished")
        self._publish_frame(np.zeros((2, 2, 3), np.uint8), now_us(), self.next)
        self.next += 1
        self._stop.wait(0.005)

    def _close(self) -> None:
        self.closed += 1


def test_a_lost_device_is_retried_with_doubling_back_off_and_its_sequence_goes_on():
    camera = FlakyCamera(before=5, refusals=4)
    with camera:
        wait_for(lambda: camera.retrying)
        status = camera.status()
        assert any(status.startswith(f"disconnected, retrying ({reason}) every ≤ 0.2 s, ")
                   for reason in ("flaky camera vanished", "flaky camera is not there")), status
        assert camera.is_connected and camera.ended is None and camera.latest().sequence == 4
        wait_for(lambda: camera.counters.reconnects == 1)
        wait_for(lambda: camera.latest().sequence >= 10)
        sequences = []
        wait_for(lambda: sequences.append(camera.latest().sequence) or len(sequences) > 20)
        assert not camera.retrying and camera.status().startswith("connected, ")
        counts = camera.counters
    assert (counts.reconnects, counts.dropped, counts.errors) == (1, 0, 0)
    assert sequences == sorted(sequences)  # the frames after the reopen follow the ones before
    waits = np.diff(camera.opens[1:])  # first retry after 0.05 s, then 0.1, 0.2, 0.2, 0.2 (the longest)
    assert len(waits) == 4 and all(0.9 * w <= got < w + 0.15 for w, got in zip((0.1, 0.2, 0.2, 0.2), waits)), waits
    assert camera.closed == 1 + 4 + 1  # the lost device, each refused reopen, the disconnect
    assert not reader_threads()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 10**9), st.booleans()), max_size=40))
def test_latest_slot_keeps_only_the_newest_and_counts_unread_replacements(steps):
    slot: LatestSlot[int] = LatestSlot()
    t_us, replaced = 0, 0
    for value, (interval, read) in enumerate(steps):
        t_us += interval
        replaced += slot.put(value, t_us)
        if read:
            assert slot.get() == value
    assert slot.get() == (len(steps) - 1 if steps else None)
    assert replaced == sum(1 for (_, r) in steps[:-1] if not r)
    summary = slot.summary()
    assert summary == "no sample yet" if not steps else "age" in summary


# --- depthai: a host-only ReplayVideo pipeline through the OAK frame path -----------------------------


def replay_builder(video: Path, frame_type: dai.ImgFrame.Type, loop: bool) -> Callable:
    def build() -> tuple[dai.Pipeline, dai.MessageQueue]:
        pipeline = dai.Pipeline(False)
        replay = pipeline.create(dai.node.ReplayVideo)
        replay.setReplayVideoFile(video)
        replay.setLoop(loop)
        replay.setFps(30)
        replay.setOutFrameType(frame_type)
        return pipeline, replay.out.createOutputQueue(maxSize=4, blocking=False)
    return build


@pytest.mark.parametrize("frame_type", [dai.ImgFrame.Type.RGB888i, dai.ImgFrame.Type.BGR888i])
def test_replay_frames_reach_the_latest_slot_as_rgb_with_host_times(tmp_path, frame_type):
    video = write_video(tmp_path / "oak.mp4", frames=12, size=(48, 64))
    source = DepthaiFrameSource("replay", replay_builder(video, frame_type, loop=True))
    with source:
        seen = []
        wait_for(lambda: source.counters.samples >= 20)
        for _ in range(5):
            wait_for(lambda: source.latest().sequence not in {r.sequence for r in seen})
            reading = source.latest()
            lag_us = now_us() - reading.t_us
            assert -2_000 < lag_us < 1_000_000, lag_us
            assert_frame(reading.image, reading.sequence % 12, (48, 64))
            seen.append(reading)
        assert [r.sequence for r in seen] == sorted({r.sequence for r in seen})
        assert all(b.t_us > a.t_us for a, b in zip(seen, seen[1:]))
        status = source.status()
        rate = float(status.split(", ")[1].removesuffix(" Hz"))
        assert status.startswith("connected, ") and 15 < rate < 45, status
    assert source.status() == "disconnected" and not reader_threads()


def test_replay_end_stops_the_reader_with_a_reason(tmp_path):
    video = write_video(tmp_path / "short.mp4", frames=6)
    source = DepthaiFrameSource("replay", replay_builder(video, dai.ImgFrame.Type.RGB888i, loop=False))
    with source:
        wait_for(lambda: source.ended)
        assert source.ended == "the depthai pipeline stopped"
        assert 1 <= source.counters.samples <= 6 and source.latest() is not None
        assert source.status().startswith("stopped (the depthai pipeline stopped)")
    assert not reader_threads()


def test_replay_reports_the_size_its_frames_have_when_it_differs_from_the_request(tmp_path):
    video = write_video(tmp_path / "small.mp4", frames=12, size=(48, 64))
    source = DepthaiFrameSource("replay", replay_builder(video, dai.ImgFrame.Type.RGB888i, loop=True),
                                requested=CameraFormat(640, 480, 30))
    with source:
        wait_for(lambda: source.counters.samples >= 2)
        assert (source.negotiated.width, source.negotiated.height) == (64, 48)
        assert ", negotiated 64×48" in source.status() and "(asked 640×480 at 30 fps)" in source.status()
        assert "resized" not in source.status()  # depthai frames are delivered as they come
    with pytest.raises(DeviceNotConnectedError, match="not connected"):
        _ = source.negotiated


@pytest.mark.skipif(sys.platform != "linux", reason="dai.Clock and time.monotonic share CLOCK_MONOTONIC on Linux")
def test_depthai_clock_is_the_host_monotonic_clock():
    assert abs(host_clock_offset_us()) < 1_000


def test_absent_oak_fails_fast_with_one_line():
    camera = OakCamera(OakCameraConfig(device_id="14442C10D13EABCE00"))
    start = time.monotonic()
    with pytest.raises(UserError) as error:
        camera.connect()
    elapsed = time.monotonic() - start
    assert str(error.value).startswith("no OAK camera found (device id 14442C10D13EABCE00); connected: ")
    assert "\n" not in str(error.value)
    assert elapsed < 5.0, elapsed
    assert not camera.is_connected and not reader_threads()


@pytest.mark.parametrize("options, message", [
    ({"socket": "CAM_Z"}, "unknown OAK camera socket 'CAM_Z'"),
    ({"width": 0}, "size must be positive"),
    ({"fps": float("nan")}, "fps must be a positive number"),
])
def test_bad_oak_options_are_user_errors(options, message):
    with pytest.raises(UserError, match=message):
        OakCameraConfig(**options)


# --- OpenCV: video files paced like a live camera, absent sources ------------------------------------


def test_file_is_paced_at_its_own_fps_in_rgb(tmp_path):
    video = write_video(tmp_path / "paced.mp4", frames=20, fps=20)
    camera = OpenCVCamera(OpenCVCameraConfig(str(video), width=64, height=48, fps=30))
    readings = []
    start = time.monotonic()
    with camera:
        def collect() -> bool:
            reading = camera.latest()
            if reading is not None and (not readings or reading.sequence != readings[-1].sequence):
                readings.append(reading)
            return camera.ended
        wait_for(collect)
        elapsed = time.monotonic() - start
        assert camera.ended == f"end of {video} after 20 frames"
        counts = camera.counters
    assert counts.samples + counts.dropped == 20 and counts.errors == 0
    # paced at the file's own 20 fps (at 30 it would end by 0.67 s): the end comes one period after frame 19 is
    # due, never sooner; the upper bound is a hang guard for a busy CPU
    assert 19 / 20 <= elapsed < 20 / 20 + 2.0, elapsed
    for reading in readings:
        assert_frame(reading.image, reading.sequence, (48, 64))
    sequences = [r.sequence for r in readings]
    assert sequences == sorted(set(sequences)) and len(readings) >= 15
    steps = np.diff([r.t_us for r in readings]) / np.diff(sequences)
    assert np.median(steps) == pytest.approx(50_000, abs=10_000)


def test_looping_file_keeps_counting_and_is_resized(tmp_path):
    video = write_video(tmp_path / "loop.mp4", frames=8, fps=30)
    camera = OpenCVCamera(OpenCVCameraConfig(str(video), width=32, height=24, loop=True))
    with camera:
        wait_for(lambda: (r := camera.latest()) is not None and r.sequence >= 20)
        reading = camera.latest()
        assert_frame(reading.image, reading.sequence % 8, (24, 32))
        assert camera.ended is None and "Hz" in camera.status()
        wait_for(lambda: camera.counters.unread >= 3)  # nobody reads: newer frames replace unread ones
    assert not reader_threads()


def test_absent_or_unreadable_sources_are_user_errors(tmp_path):
    garbage = tmp_path / "garbage.mp4"
    garbage.write_bytes(b"\x00not a video" * 50)
    cases = [(str(tmp_path / "missing.mp4"), f"video file {tmp_path / 'missing.mp4'} not found"),
             (str(garbage), f"video file {garbage} cannot be read"),
             (97, "no camera at 97"),
             ("/dev/video97", "no camera at '/dev/video97'")]
    for source, message in cases:
        camera = OpenCVCamera(OpenCVCameraConfig(source))
        with pytest.raises(UserError) as error:
            camera.connect()
        assert str(error.value).startswith(message) and "\n" not in str(error.value)
        assert not camera.is_connected
    assert not reader_threads()
    with pytest.raises(UserError, match="fps must be a positive number"):
        OpenCVCameraConfig(0, fps=float("inf"))


def test_opencv_reads_back_what_the_file_negotiates_and_says_so_when_it_differs(tmp_path):
    video = write_video(tmp_path / "small.mp4", frames=30, fps=20, size=(48, 64))
    camera = OpenCVCamera(OpenCVCameraConfig(str(video), width=32, height=24, fps=30, loop=True))
    assert camera.requested == CameraFormat(32, 24, 30)
    with pytest.raises(DeviceNotConnectedError, match=f"^OpenCV camera {video} is not connected"):
        _ = camera.negotiated
    with camera:
        assert camera.negotiated == CameraFormat(64, 48, 20.0)
        wait_for(lambda: camera.latest() is not None)
        assert camera.latest().image.shape == (24, 32, 3)  # resized to the request, and the status says so
        wait_for(lambda: "Hz" in camera.status())
        assert camera.status().endswith(", negotiated 64×48 at 20 fps (asked 32×24 at 30 fps; frames resized to 32×24)")
    matching = OpenCVCamera(OpenCVCameraConfig(str(video), width=64, height=48, fps=20))
    with matching:
        assert matching.negotiated == CameraFormat(64, 48, 20.0)
        wait_for(lambda: matching.latest() is not None)
        assert "negotiated" not in matching.status()


def test_camera_format_comparison():
    asked = CameraFormat(640, 480, 30)
    assert not CameraFormat(640, 480, 30.2).differs_from(asked) and not CameraFormat(640, 480).differs_from(asked)
    assert CameraFormat(640, 480, 15).differs_from(asked) and CameraFormat(1280, 720, 30).differs_from(asked)
    assert str(CameraFormat(1280, 720, 29.97)) == "1280×720 at 29.97 fps" and str(CameraFormat(64, 48)) == "64×48"
