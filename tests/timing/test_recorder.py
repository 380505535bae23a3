"""Recorder: Snapshots into raw episode folders that every reader opens, a queue that drops instead of
blocking, a recording that says when it falls behind, writer errors kept and reported, and a recording
killed with SIGKILL that still replays. Its fsyncs and the whole live path are in test_recorder_fsync.py."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers.simulated_rig import frame_picture, synthetic_snapshot
from tests.integration.test_convert_safety import tmpfs
from touchanything.core.errors import UserError
from touchanything.core.snapshot import FPS
from touchanything.core.temporary_files import recorded_stream
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_streams import read_glove, read_hands
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter, write_grids_from_glove
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.devices.rig.recorder import Recorder, RecorderConfig, describe_error
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource

HERE = Path(__file__).resolve().parent
TESTS = HERE.parent


def record_forever(folder: str) -> None:
    """The crash test's child process: synthetic Snapshots at 30 fps into a Recorder until killed."""
    recorder = Recorder(RecorderConfig(Path(folder)))
    recorder.start()
    start, k = time.monotonic(), 0
    print("recording", flush=True)
    while True:
        time.sleep(max(0.0, start + k / FPS - time.monotonic()))
        recorder.write(synthetic_snapshot(k))
        k += 1


def check_synthetic(episode, frames: int) -> None:
    """Every stream of frames 0..frames-1 holds what synthetic_snapshot wrote."""
    video = episode.views["ego"]  # the episode's own reader: also a stream cut short
    for k in range(frames):
        expected = synthetic_snapshot(k)
        assert np.abs(video.read(k).astype(int) - expected.images["ego"]).mean() < 8, k
        valid = expected.joints_valid
        assert np.array_equal(episode.wilor.valid[k], valid)
        assert np.array_equal(episode.wilor.joints[k][valid], expected.joints.reshape(2, 21, 3)[valid])
        present = expected.glove_present
        assert np.array_equal(episode.glove.present[k], present)
        assert np.array_equal(episode.glove.raw[k][present], expected.pressure_raw[present])
        assert episode.glove.timestamps_us is None or episode.glove.timestamps_us[k] == expected.t_us
        assert episode.trackers is None or episode.trackers.valid[k, 0] == (k >= 10)


def test_a_recording_replays_with_every_stream(tmp_path):
    folder = tmp_path / "Lab" / "task" / "take1"
    with Recorder(RecorderConfig(folder)) as recorder:
        for k in range(40):
            recorder.write(synthetic_snapshot(k))
    counters = recorder.counters
    assert (counters.written, counters.dropped, counters.failed, counters.queued) == (40, 0, 0, 0)
    assert recorder.status().startswith(f"stopped {folder}: 40 frames, 0 dropped, queue 0/60,")
    with open_episode(folder) as episode:
        assert episode.num_frames == 40 and episode.scene == "Lab"
        assert episode.pressure.grids.shape == (40, 2, 21, 21)
        check_synthetic(episode, 40)
        assert np.array_equal(episode.trackers.poses[10:, 0], np.tile(np.arange(10, 40)[:, None], 7))
        assert [p for p in episode.problems if "missing" in p] == [
            f"{folder / name}: missing required file" for name in ("left.mp4", "right.mp4")]
        assert episode.glove.timestamps_us is not None


def test_replay_into_a_recorder_copies_the_episode(episode_dir, tmp_path):
    with open_episode(episode_dir) as source, Recorder(RecorderConfig(tmp_path / "copy", queue_frames=100)) as rec:
        for snapshot in ReplaySource(source, ReplayConfig(speed=None)):
            rec.write(snapshot)
    with open_episode(episode_dir) as source, open_episode(tmp_path / "copy") as copy:
        assert copy.num_frames == source.num_frames == 40
        for name in ("wilor", "rokoko"):
            assert np.array_equal(copy.hands(name).valid, source.hands(name).valid)
            assert np.array_equal(copy.hands(name).joints, source.hands(name).joints)
        assert np.array_equal(copy.glove.raw, source.glove.raw)
        assert np.array_equal(copy.glove.present, source.glove.present)
        assert np.array_equal(copy.trackers.valid, source.trackers.valid)
        assert np.array_equal(copy.trackers.poses, source.trackers.poses)
        assert np.allclose(copy.pressure.grids, source.pressure.grids, equal_nan=True)
        for view in source.view_names:
            a, b = copy.views[view].read(39), source.views[view].read(39)
            assert np.abs(a.astype(int) - b).mean() < 8


def test_streams_keep_one_entry_per_frame_when_sources_come_and_go(tmp_path):
    with RawEpisodeWriter(tmp_path / "ep") as writer:
        for k in range(8):
            frame = EpisodeFrame(images={"ego": frame_picture(k)} if k not in (4, 5) else {})
            if k >= 2:
                frame.images["wrist_left"] = frame_picture(50 + k)
            if k % 2 == 0:
                frame.wilor = (np.full((2, 21, 3), k, np.float32), np.array([True, True]))
            if k >= 3 and k != 6:
                frame.glove = (np.full((2, 256), k, np.uint8), np.array([True, True]), np.zeros((2, 4), np.float32))
            writer.write(frame)
    hands, _ = read_hands(tmp_path / "ep" / "wilor_hands.json")
    assert hands.valid[:, 0].tolist() == [k % 2 == 0 for k in range(8)] and hands.joints[6, 0, 0, 0] == 6
    glove, _ = read_glove(tmp_path / "ep" / "jq_pressure.json")
    assert glove.present[:, 0].tolist() == [False] * 3 + [True] * 3 + [False, True] and glove.raw[7, 0, 0] == 7
    with VideoReader(tmp_path / "ep" / "chest.mp4") as ego, VideoReader(tmp_path / "ep" / "left.mp4") as wrist:
        assert ego.num_frames == wrist.num_frames == 8
        for k, shown in enumerate([0, 1, 2, 3, 3, 3, 6, 7]):  # the last picture repeats while missing
            assert np.abs(ego.read(k).astype(int) - frame_picture(shown)).mean() < 8
        assert wrist.read(0).max() < 20 and wrist.read(1).max() < 20  # black before the view appears
        assert np.abs(wrist.read(5).astype(int) - frame_picture(55)).mean() < 8


def test_a_full_queue_drops_frames_and_write_never_blocks(tmp_path):
    recorder = Recorder(RecorderConfig(tmp_path / "ep", queue_frames=2))
    snapshots = [synthetic_snapshot(k) for k in range(60)]
    recorder.write(snapshots[0])  # before start: dropped
    assert recorder.counters.dropped == 1
    recorder.start()
    durations = []
    for snapshot in snapshots:
        began = time.perf_counter()
        recorder.write(snapshot)
        durations.append(time.perf_counter() - began)
    counters = recorder.stop()
    recorder.write(snapshots[0])  # after stop: dropped
    # a blocking write would wait for a frame to be encoded (tens of ms) every time the queue is full
    assert np.median(durations) < 0.005 and max(durations) < 0.5
    assert counters.written >= 2 and counters.dropped >= 1 and counters.written + counters.dropped == 60
    assert recorder.counters.dropped == counters.dropped + 1
    with open_episode(tmp_path / "ep") as episode:
        assert episode.num_frames == counters.written


def test_a_recording_is_behind_while_its_queue_is_over_a_quarter_full(tmp_path):
    recorder = Recorder(RecorderConfig(tmp_path / "ep", queue_frames=40))
    snapshots = [synthetic_snapshot(k) for k in range(40)]
    recorder.start()
    behind = []
    # The 40 writes take microseconds, a frame's encoding milliseconds; a long GIL switch interval keeps a busy
    # machine from handing the writer thread the interpreter between two writes (it then kept up in a CI run).
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1.0)
    try:
        for snapshot in snapshots:
            recorder.write(snapshot)
            behind.append(recorder.is_behind)
    finally:
        sys.setswitchinterval(interval)
    deadline = time.monotonic() + 30
    while recorder.counters.queued and time.monotonic() < deadline:
        time.sleep(0.01)
    assert behind[:10] == [False] * 10 and behind[-1] and not recorder.is_behind
    assert recorder.stop().written + recorder.counters.dropped == 40


def test_the_writer_keeps_no_glove_history_in_memory(tmp_path):
    """The grids are computed from the glove stream read back at close, so a long recording's memory stays
    flat (the raw bytes of every frame used to be kept: ~0.6 kB a frame, 1.1 MB a minute)."""
    import tracemalloc

    frame = synthetic_snapshot(3)
    with RawEpisodeWriter(tmp_path / "ep") as writer:
        glove = EpisodeFrame(glove=(frame.pressure_raw, frame.glove_present, frame.imu_wxyz))
        for _ in range(100):
            writer.write(glove)
        tracemalloc.start()
        before = tracemalloc.take_snapshot()
        for _ in range(2000):
            writer.write(glove)
        grown = sum(stat.size_diff for stat in tracemalloc.take_snapshot().compare_to(before, "filename"))
        tracemalloc.stop()
    assert grown < 100_000, grown
    with open_episode(tmp_path / "ep") as episode:
        expected = np.where(frame.glove_present[:, None], frame.pressure_raw, 0)
        assert episode.num_frames == 2100 and np.array_equal(episode.glove.raw[-1], expected)
        assert episode.pressure.grids.shape == (2100, 2, 21, 21)


def test_bad_folders_and_settings_are_user_errors(tmp_path):
    with pytest.raises(UserError, match="at least 1 frame"):
        RecorderConfig(tmp_path / "ep", queue_frames=0)
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match="cannot create the episode folder"):
        Recorder(RecorderConfig(tmp_path / "file" / "ep")).start()
    with Recorder(RecorderConfig(tmp_path / "ep")) as recorder:
        recorder.write(synthetic_snapshot(0))
        with pytest.raises(RuntimeError, match="already recording"):
            recorder.start()
    with pytest.raises(UserError, match="already holds a recording; choose a new folder"):
        Recorder(RecorderConfig(tmp_path / "ep")).start()


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_a_full_disk_is_reported_and_the_frames_said_to_replay_do(tmp_path):
    disk = tmpfs(tmp_path / "disk", "256k")
    try:
        folder = disk / "ep"
        recorder = Recorder(RecorderConfig(folder))
        recorder.start()
        for k in range(600):
            recorder.write(synthetic_snapshot(k))
            deadline = time.monotonic() + 10
            while recorder.counters.written + recorder.counters.failed <= k and time.monotonic() < deadline:
                time.sleep(0.002)
            if recorder.counters.failed:
                break
        assert "failed: No space left on device" in recorder.status() and recorder.error.startswith("No space left")
        with pytest.raises(UserError, match=r"failed: No space left on device") as failure:
            recorder.stop()
        said = re.search(r"; (\d+) of the (\d+) frames written before replay$", str(failure.value))
        assert said is not None and int(said[2]) == recorder.counters.written > 0, str(failure.value)
        with open_episode(folder) as episode:  # what the message says is what replays
            assert episode.num_frames == int(said[1])
            replayed = [s.frame_index for s in ReplaySource(episode, ReplayConfig(speed=None))]
            assert replayed == list(range(int(said[1])))
    finally:
        subprocess.run(["umount", str(disk)], check=True)


@pytest.mark.multiprocess
def test_a_killed_recording_replays_up_to_its_last_second_and_its_grids_can_be_rebuilt(tmp_path):
    folder = tmp_path / "Lab" / "task" / "killed"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS.parent), str(TESTS), str(HERE)])}
    child = subprocess.Popen(
        [sys.executable, "-c", "import sys; from test_recorder import record_forever; record_forever(sys.argv[1])",
         str(folder)], stdout=subprocess.PIPE, env=env, cwd=HERE)
    try:
        assert child.stdout.readline() == b"recording\n"
        began = time.monotonic()
        time.sleep(3.0)
        child.send_signal(signal.SIGKILL)
        elapsed = time.monotonic() - began
    finally:
        child.kill()
        child.wait()
    with open_episode(folder) as episode:
        frames = episode.num_frames
        assert frames >= (elapsed - 1) * FPS * 0.8, (frames, elapsed)
        # the streams are still under their marked temporary names: a recording cut short names no file
        assert not any((folder / name).exists() for name in ("chest.mp4", "wilor_hands.json", "jq_pressure.json"))
        rows = len(recorded_stream(folder, "wilor_hands.json").read_text().splitlines())
        assert rows >= frames and len(recorded_stream(folder, "jq_pressure.json").read_text().splitlines()) >= frames
        assert any("chest.mp4: read from .chest.mp4.partial-" in p and "a recording cut short" in p
                   for p in episode.problems)
        assert episode.pressure is None
        assert any("pressure_grids.npz: missing required file" in p and f"touchanything grids {folder}" in p
                   for p in episode.problems)
        check_synthetic(episode, frames)
        replayed = [s.frame_index for s in ReplaySource(episode, ReplayConfig(speed=None))]
        assert replayed == list(range(frames))
    write_grids_from_glove(folder)  # what `touchanything grids FOLDER` runs
    with open_episode(folder) as episode:
        assert episode.num_frames == frames and episode.pressure.grids.shape == (frames, 2, 21, 21)
        assert not any("missing" in p for p in episode.problems if "pressure_grids" in p)


def test_a_writer_error_is_one_line_without_its_type_when_it_is_a_users():
    assert describe_error(UserError("ep/left.mp4: appeared while the episode was written")) == \
        "ep/left.mp4: appeared while the episode was written"
    assert describe_error(OSError(28, "No space left on device", "ep/chest.mp4")) == "No space left on device (ep/chest.mp4)"
    assert describe_error(ValueError("odd")) == "ValueError: odd"
