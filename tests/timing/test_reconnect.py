"""Cameras that go away and come back, through real OS channels: an OpenCV camera opened through a symlink
(standing in for /dev/v4l/by-id/…) to a real video file, whose link is removed and re-created, read by the
rig clock beside a second camera; and a host-only depthai pipeline on the OAK frame path, whose stream
closing is a lost device. The retry itself is the shared `ThreadedSource` one (the glove's too)."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import depthai as dai
import numpy as np

from touchanything.core.errors import UserError
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.hardware.oak_camera import DepthaiFrameSource
from touchanything.devices.hardware.opencv_camera import OpenCVCamera, OpenCVCameraConfig
from touchanything.devices.hardware.threaded_source import now_us
from touchanything.devices.rig.rig_clock import RigClock, RigClockConfig
from touchanything.devices.rig.rig_inputs import RigInput, camera_fill

RED, GREEN, BLUE_STEP = 200, 50, 8


def wait_for(predicate: Callable[[], object], what: str, timeout: float = 10.0) -> object:
    deadline = time.monotonic() + timeout
    while not (result := predicate()):
        assert time.monotonic() < deadline, f"{what} did not happen within {timeout} s"
        time.sleep(0.005)
    return result


def reader_threads() -> list[str]:
    return [t.name for t in threading.enumerate() if t.name.endswith(" reader")]


def write_video(path: Path, frames: int, blue_offset: int = 0) -> Path:
    """Solid 64×48 frames: red 200, green 50, blue = 8 × (frame index + blue_offset)."""
    with VideoWriter(path, fps=30, crf=0) as writer:
        for i in range(frames):
            writer.write(np.full((48, 64, 3), (RED, GREEN, BLUE_STEP * (i + blue_offset)), np.uint8))
    return path


def is_frame_of(image: np.ndarray, frames: int, blue_offset: int = 0) -> bool:
    r, g, b = image.reshape(-1, 3).mean(axis=0)
    blues = BLUE_STEP * (np.arange(frames) + blue_offset)
    return abs(r - RED) < 8 and abs(g - GREEN) < 8 and np.min(np.abs(blues - b)) < 4


def test_vanished_camera_retries_and_its_view_leaves_and_rejoins_the_snapshots(tmp_path):
    ego_video = write_video(tmp_path / "ego.mp4", frames=10)
    wrist_video = write_video(tmp_path / "wrist.mp4", frames=10, blue_offset=15)
    by_id = tmp_path / "v4l" / "by-id"
    by_id.mkdir(parents=True)
    link = by_id / "usb-Test_Cam_ego-video-index0"
    link.symlink_to(ego_video)
    ego = OpenCVCamera(OpenCVCameraConfig(str(link), width=64, height=48, loop=True))  # default back-off
    wrist = OpenCVCamera(OpenCVCameraConfig(str(wrist_video), width=64, height=48, loop=True))
    clock = RigClock([RigInput("ego", ego, camera_fill("ego")), RigInput("wrist_left", wrist, camera_fill("wrist_left"))],
                     RigClockConfig(rate_hz=30, stale_after_ms=200))
    snapshots = []
    clock.subscribe(snapshots.append)
    with ego, wrist, clock:
        wait_for(lambda: snapshots and set(snapshots[-1].images) == {"ego", "wrist_left"}, "both views")
        last_before = ego.latest().sequence

        link.unlink()  # the camera is unplugged: its by-id link disappears
        gone_us = now_us()
        status = wait_for(lambda: (s := ego.status()).startswith("disconnected, retrying (") and s, "retrying")
        assert f"({link} vanished) every ≤ 2 s" in status and status.endswith(", 0 reconnects, 0 dropped")
        assert ego.is_connected and ego.retrying and ego.ended is None
        wait_for(lambda: "not found" in (ego.down_reason or ""), "a failed reopen")  # the reopen fails while away
        assert ego.down_reason == f"video file {link} not found" and ego.counters.reconnects == 0
        time.sleep(1.0)

        link.symlink_to(ego_video)  # plugged in again under the same stable name
        back_us = now_us()
        wait_for(lambda: ego.counters.reconnects == 1, "the reopen", timeout=2.5)  # retried every ≤ 2 s
        reopened_s = (now_us() - back_us) / 1e6
        fresh = wait_for(lambda: (r := ego.latest()) and r.t_us > back_us and r, "a frame after the return")
        wait_for(lambda: snapshots[-1].t_us > fresh.t_us and "ego" in snapshots[-1].images, "ego in a snapshot")
        status = ego.status()
    assert reopened_s < 2.5 and fresh.sequence > last_before and is_frame_of(fresh.image, 10)
    assert status.startswith("connected, ") and ", 1 reconnects" in status and "retrying" not in status

    # The view leaves the snapshots while the camera is away (the wrist view goes on), and rejoins.
    away = [s for s in snapshots if gone_us + 250_000 < s.t_us < back_us]
    assert len(away) >= 20, len(away)
    for snapshot in away:
        assert set(snapshot.images) == {"wrist_left"} and is_frame_of(snapshot.images["wrist_left"], 10, 15)
        assert snapshot.source_status["ego"].startswith("stale") and "disconnected, retrying" in snapshot.source_status["ego"]
        assert snapshot.source_status["wrist_left"].startswith("ok")
    # from the moment the camera knows it is gone its last frame is not used, however young it is
    assert all("ego" not in s.images for s in snapshots if s.source_status["ego"].find("retrying") >= 0)
    returned = [s for s in snapshots if s.t_us > fresh.t_us]
    assert returned and all(set(s.images) == {"ego", "wrist_left"} for s in returned)
    assert all(is_frame_of(s.images["ego"], 10) for s in returned)
    assert not reader_threads()


def test_a_file_that_ends_is_an_end_not_a_lost_device(tmp_path):
    link = tmp_path / "clip-link.mp4"
    link.symlink_to(write_video(tmp_path / "clip.mp4", frames=6))
    camera = OpenCVCamera(OpenCVCameraConfig(str(link), width=64, height=48))
    with camera:
        wait_for(lambda: camera.ended, "the end of the file")
        time.sleep(0.3)
        assert camera.ended == f"end of {link} after 6 frames" and not camera.retrying
        assert camera.counters.reconnects == 0 and camera.status().startswith("stopped (end of ")
    assert not reader_threads()


def test_oak_frame_path_reopens_a_device_whose_stream_closed(tmp_path):
    """A `live` depthai source: its queue closing is a lost device (the end of a non-looping ReplayVideo
    stands in for an OAK dropping off the bus); reopening goes through the builder, which fails while the
    video's link (the stand-in for the device id) is absent, as `open_device` does."""
    video = write_video(tmp_path / "oak.mp4", frames=8)
    link = tmp_path / "oak-device"
    link.symlink_to(video)
    failed_builds = []

    def build() -> tuple[dai.Pipeline, dai.MessageQueue]:
        if not link.exists():
            failed_builds.append(time.monotonic())
            raise UserError(f"no OAK camera found (device id {link.name}); connected: none")
        pipeline = dai.Pipeline(False)
        replay = pipeline.create(dai.node.ReplayVideo)
        replay.setReplayVideoFile(link)
        replay.setLoop(False)
        replay.setFps(30)
        replay.setOutFrameType(dai.ImgFrame.Type.RGB888i)
        return pipeline, replay.out.createOutputQueue(maxSize=4, blocking=False)

    source = DepthaiFrameSource("replay OAK", build, live=True, reconnect_backoff_s=(0.05, 0.4))
    with source:
        wait_for(lambda: source.counters.samples >= 3, "first frames")
        link.unlink()
        status = wait_for(lambda: "no OAK camera found" in (s := source.status()) and s, "a failed reopen")
        assert status.startswith("disconnected, retrying (no OAK camera found (device id oak-device); connected: none)"
                                 " every ≤ 0.4 s")
        assert source.is_connected and source.ended is None
        time.sleep(1.2)
        before = source.latest().sequence
        link.symlink_to(video)
        back = time.monotonic()
        fresh = wait_for(lambda: (r := source.latest()) and r.sequence > before and r, "frames after the return")
        assert is_frame_of(fresh.image, 8) and source.counters.reconnects >= 1
    waits = np.diff([t for t in failed_builds if t < back])  # doubling from 0.1 s, capped at the longest
    assert len(waits) >= 3 and waits[0] < 0.3 and 0.3 < waits[-1] < 0.4 + 0.3, waits
    assert not reader_threads()
