"""Recorder: Snapshots into raw episode folders that every reader opens, a queue that drops instead of
blocking, writer errors kept and reported, a recording killed with SIGKILL that still replays, fsyncs on
the `fsync_s` cadence on the writer thread (counted through a wrapper of os.fsync), and the whole live
path: simulated devices → adapters → rig clock → recorder → episode reader."""
from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from helpers.simulated_rig import frame_picture, simulated_rig
from touchanything.app.sessions.scene import read_scene
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_streams import read_glove, read_hands
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter, write_grids_from_glove
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.devices.errors import UserError
from touchanything.devices.hardware.threaded_source import now_us
from touchanything.devices.rig.recorder import Recorder, RecorderConfig
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.rig.rig_clock import RigClock
from touchanything.devices.snapshot import FPS, Snapshot

TESTS = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Fsync:
    """One os.fsync call: the file or directory it synced, its size then, when, and on which thread."""

    path: Path
    size: int
    t: float
    thread: str


@pytest.fixture
def fsyncs(monkeypatch) -> list[Fsync]:
    """Every os.fsync call from now on, recorded by a wrapper that calls the real os.fsync."""
    calls: list[Fsync] = []
    real = os.fsync

    def counting_fsync(fd: int) -> None:
        calls.append(Fsync(Path(os.readlink(f"/proc/self/fd/{fd}")), os.fstat(fd).st_size, time.monotonic(),
                           threading.current_thread().name))
        real(fd)

    monkeypatch.setattr(os, "fsync", counting_fsync)
    return calls


def synthetic_snapshot(k: int) -> Snapshot:
    """Frame k of a recording that names k in every stream: picture, joints, glove ramp (left glove only
    on even frames), trackers from frame 10 on."""
    joints = np.full((42, 3), k / 7, np.float32)
    joints[:, 2] += 40
    raw = np.stack([(np.arange(256) + k) % 256, np.full(256, k % 256)]).astype(np.uint8)
    return Snapshot(
        frame_index=k, t_us=1_000_000 + k * 33_333, images={"ego": frame_picture(k)},
        joints=joints, joints_valid=np.array([True, k % 3 != 0]),
        pressure_raw=raw, imu_wxyz=np.array([[1, 0, 0, 0], [0, 1, 0, 0]], np.float32),
        glove_present=np.array([k % 2 == 0, True]),
        trackers={"chest": np.full(7, k, np.float32)} if k >= 10 else {},
    )


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
    with VideoReader(episode.path / "chest.mp4") as video:
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
    recorder.start()
    behind = []
    for k in range(40):  # queued in microseconds, encoded in milliseconds
        recorder.write(synthetic_snapshot(k))
        behind.append(recorder.is_behind)
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


def test_a_disk_error_is_reported_and_what_was_written_is_kept(tmp_path):
    folder = tmp_path / "ep"
    folder.mkdir()
    (folder / "vive_poses.json").symlink_to("/dev/full")  # the disk fills up when the trackers appear
    recorder = Recorder(RecorderConfig(folder))
    recorder.start()
    for k in range(20):
        recorder.write(synthetic_snapshot(k))
    deadline = time.monotonic() + 10
    while recorder.counters.written + recorder.counters.failed < 20 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert "failed: No space left on device" in recorder.status() and recorder.error.startswith("No space left")
    kept = r"failed: No space left on device \(.*vive_poses.json\); the 10 frames written before are kept"
    with pytest.raises(UserError, match=kept):
        recorder.stop()
    assert (recorder.counters.written, recorder.counters.failed) == (10, 10)
    (folder / "vive_poses.json").unlink()  # reading /dev/full never ends
    with open_episode(folder) as episode:
        assert episode.num_frames == 10 and episode.pressure.grids.shape == (10, 2, 21, 21)
        episode.trackers = None
        check_synthetic(episode, 10)


@pytest.mark.multiprocess
def test_a_killed_recording_replays_up_to_its_last_second_and_its_grids_can_be_rebuilt(tmp_path):
    folder = tmp_path / "Lab" / "task" / "killed"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS.parent), str(TESTS)])}
    child = subprocess.Popen(
        [sys.executable, "-c", "import sys; from test_recorder import record_forever; record_forever(sys.argv[1])",
         str(folder)], stdout=subprocess.PIPE, env=env, cwd=TESTS)
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
        rows = len((folder / "wilor_hands.json").read_text().splitlines())
        assert rows >= frames and len((folder / "jq_pressure.json").read_text().splitlines()) >= frames
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


def test_live_rig_to_recording_and_back(tmp_path, fsyncs):
    snapshots: list[Snapshot] = []
    folder = tmp_path / "Lab" / "live" / "take"
    with simulated_rig(tmp_path) as live:
        deadline = time.monotonic() + 10
        while any(i.source.latest() is None for i in live.inputs) and time.monotonic() < deadline:
            time.sleep(0.02)
        recorder = Recorder(RecorderConfig(folder))
        clock = RigClock(live.inputs)
        clock.subscribe(snapshots.append)
        clock.subscribe(recorder.write)
        recorder.start()
        started_us = now_us()
        with clock:
            time.sleep(2.0)
            clock.unsubscribe(recorder.write)
            written_ticks = len(snapshots)
            live_status = recorder.status()
        counters = recorder.stop()
    assert live_status.startswith(f"recording {folder}:")
    synced = {f.thread for f in fsyncs if f.path.is_relative_to(folder.resolve())}
    assert synced == {"recorder"}  # the writer thread's work, never the rig clock's
    assert counters.dropped == 0 and counters.written == written_ticks and 45 <= written_ticks <= 75
    recorded = snapshots[:written_ticks]
    with open_episode(folder) as episode:
        assert episode.num_frames == written_ticks and episode.view_names == ("ego",)
        assert np.array_equal(episode.glove.timestamps_us, [s.t_us for s in recorded])
        assert episode.glove.timestamps_us[0] >= started_us
        for k, s in enumerate(recorded):
            assert np.array_equal(episode.glove.present[k], s.glove_present)
            assert np.array_equal(episode.glove.raw[k], s.pressure_raw)
            assert np.array_equal(episode.glove.quat_wxyz[k], s.imu_wxyz)
            assert np.array_equal(episode.wilor.joints[k], s.joints.reshape(2, 21, 3))
            assert np.array_equal(episode.wilor.valid[k], s.joints_valid)
            assert np.array_equal(episode.rokoko.joints[k], s.mocap_joints.reshape(2, 21, 3))
            assert np.array_equal(episode.trackers.poses[k, 0], s.trackers["chest"])
            assert np.abs(episode.views["ego"].read(k).astype(int) - s.images["ego"]).mean() < 8
        assert episode.pressure.grids.shape == (written_ticks, 2, 21, 21)


def test_sync_fsyncs_every_file_and_each_new_directory_entry_once(tmp_path, fsyncs):
    folder = (tmp_path / "Lab" / "task" / "take").resolve()
    writer = RawEpisodeWriter(folder, durable=True)
    hands = (np.zeros((2, 21, 3), np.float32), np.array([True, True]))
    writer.write(EpisodeFrame(images={"ego": frame_picture(0)}, wilor=hands))
    writer.sync()  # the files, then the new folders' entries from the outside in, then the folder's new files
    assert not (folder / "chest.mp4").exists()  # FFmpeg creates it with x264's first packet, frames later
    assert [f.path for f in fsyncs] == [folder / "wilor_hands.json", tmp_path.resolve(), folder.parents[1],
                                        folder.parent, folder]
    assert fsyncs[0].size == len((folder / "wilor_hands.json").read_bytes()) > 0
    fsyncs.clear()
    for k in range(1, 40):
        writer.write(EpisodeFrame(images={"ego": frame_picture(k)}, wilor=hands))
    writer.sync()  # the video's file now exists: it, and the folder again for its entry
    assert [f.path for f in fsyncs] == [folder / "chest.mp4", folder / "wilor_hands.json", folder]
    fsyncs.clear()
    writer.write(EpisodeFrame(images={"ego": frame_picture(40)}, wilor=hands))
    writer.sync()  # no new file: no directory
    assert [f.path for f in fsyncs] == [folder / "chest.mp4", folder / "wilor_hands.json"]
    fsyncs.clear()
    glove = (np.ones((2, 256), np.uint8), np.array([True, True]), np.zeros((2, 4), np.float32))
    writer.write(EpisodeFrame(images={"ego": frame_picture(41)}, wilor=hands, glove=glove))
    writer.sync()  # a new stream: the folder again
    assert [f.path for f in fsyncs] == [folder / "chest.mp4", folder / "wilor_hands.json",
                                        folder / "jq_pressure.json", folder]
    fsyncs.clear()
    writer.close()  # each file after its last bytes, the grids before their rename, the folder after it
    assert [f.path for f in fsyncs] == [folder / "chest.mp4", folder / "wilor_hands.json", folder / "jq_pressure.json",
                                        folder / "pressure_grids.npz.partial.npz", folder]
    assert fsyncs[0].size == (folder / "chest.mp4").stat().st_size
    fsyncs.clear()
    with RawEpisodeWriter(tmp_path / "plain") as plain:  # not durable, never synced: nothing
        plain.write(EpisodeFrame(images={"ego": frame_picture(0)}, wilor=hands, glove=glove))
    assert fsyncs == []


def sync_rounds(fsyncs: list[Fsync], folder: Path) -> list[float]:
    """When each sync round synced wilor_hands.json (every synthetic frame has a row in it; chest.mp4 only
    exists from x264's first packet on)."""
    return [f.t for f in fsyncs if f.path == folder / "wilor_hands.json"]


def test_the_recorder_fsyncs_every_stream_on_its_cadence_on_the_writer_thread(tmp_path, fsyncs):
    folder = (tmp_path / "ep").resolve()
    recorder = Recorder(RecorderConfig(folder, fsync_s=0.5))
    recorder.start()
    began = time.monotonic()
    for k in range(75):  # 2.5 s at 30 fps from this thread, standing in for the rig clock's
        time.sleep(max(0.0, began + k / FPS - time.monotonic()))
        recorder.write(synthetic_snapshot(k))
    while recorder.counters.written < 75 and time.monotonic() < began + 20:
        time.sleep(0.01)
    elapsed = time.monotonic() - began
    during = list(fsyncs)
    counters = recorder.stop()
    assert counters.written == 75 and counters.dropped == 0
    assert {f.thread for f in fsyncs} == {"recorder"}
    rounds = sync_rounds(during, folder)
    assert elapsed / 0.5 - 3 <= len(rounds) <= elapsed / 0.5 + 1, (rounds, elapsed)
    assert rounds[0] - began >= 0.5
    gaps = np.diff(rounds)
    assert gaps.min() >= 0.5 and gaps.max() < 0.5 + 0.5, gaps  # never sooner; late by what a loaded CPU delays
    for name in ("chest.mp4", "jq_pressure.json"):  # every stream in every round
        assert len([f for f in during if f.path == folder / name]) == len(rounds)
    assert 1 <= len([f for f in during if f.path == folder / "vive_poses.json"]) <= len(rounds)  # from frame 10
    # stop(): every file once more, after its last bytes, and the grids
    last = {f.path.name: f.size for f in fsyncs[len(during):]}
    assert all(last[name] == (folder / name).stat().st_size for name in
               ("chest.mp4", "wilor_hands.json", "jq_pressure.json", "vive_poses.json"))
    assert "pressure_grids.npz.partial.npz" in last and folder.name in last


def test_the_recorder_syncs_what_waits_even_when_no_frame_comes(tmp_path, fsyncs):
    folder = (tmp_path / "ep").resolve()
    recorder = Recorder(RecorderConfig(folder, fsync_s=0.3))
    recorder.start()
    for k in range(3):
        recorder.write(synthetic_snapshot(k))
    time.sleep(1.2)
    idle = list(fsyncs)
    recorder.stop()
    hands = [f for f in idle if f.path == folder / "wilor_hands.json"]
    assert hands and hands[-1].size == (folder / "wilor_hands.json").stat().st_size  # all 3 rows on disk
    assert time.monotonic() - hands[-1].t > 0.3  # and nothing synced again while nothing was new
    assert len(sync_rounds(idle, folder)) <= 2


@pytest.mark.parametrize("fsync_s, rounds", [(0, 6), (None, 0)])
def test_fsync_after_every_frame_or_never(tmp_path, fsyncs, fsync_s, rounds):
    folder = (tmp_path / "ep").resolve()
    with Recorder(RecorderConfig(folder, fsync_s=fsync_s)) as recorder:
        for k in range(6):
            recorder.write(synthetic_snapshot(k))
    assert recorder.counters.written == 6
    close = 1 if fsync_s is not None else 0  # stop() syncs once more, unless never
    assert len(sync_rounds(fsyncs, folder)) == rounds + close
    assert len([f for f in fsyncs if f.path == folder / "jq_pressure.json"]) == rounds + close


def test_a_failed_fsync_is_a_writer_error(tmp_path, monkeypatch):
    def failing_fsync(fd: int) -> None:
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    monkeypatch.setattr(os, "fsync", failing_fsync)  # the disk fails
    folder = tmp_path / "ep"
    recorder = Recorder(RecorderConfig(folder, fsync_s=0))
    recorder.start()
    for k in range(6):
        recorder.write(synthetic_snapshot(k))
    with pytest.raises(UserError, match=r"failed: Input/output error \(.*/ep/wilor_hands.json\); the 1 frames"):
        recorder.stop()
    assert (recorder.counters.written, recorder.counters.failed) == (1, 5)
    assert (folder / "pressure_grids.npz").is_file()  # still closed and computed from what was written


def test_the_fsync_setting_of_a_scene(tmp_path):
    scene = tmp_path / "rig.toml"
    for text, fsync_s in [("", 1.0), ("[recording]\nfsync_s = 0.25", 0.25), ("[recording]\nfsync_s = 0", 0),
                          ("[recording]\nfsync_s = false", None)]:
        scene.write_text(text)
        assert read_scene(scene).recording.fsync_s == fsync_s
    expected = "expected seconds ≥ 0 (0: after every frame) or false (never)"
    for value, shown in [("-1", "-1"), ('"off"', "'off'"), ("true", "True"), ("nan", "nan"), ("inf", "inf")]:
        scene.write_text(f"[recording]\nfsync_s = {value}")
        with pytest.raises(UserError) as error:
            read_scene(scene)
        assert str(error.value) == f"{scene}: [recording] fsync_s: {expected}, got {shown}"
    scene.write_text("[recording]\nfsync = 1")
    with pytest.raises(UserError, match=r"^\S+rig.toml: \[recording\] .*'fsync'$"):
        read_scene(scene)
    for bad in (-0.5, True, float("nan")):
        with pytest.raises(UserError, match="fsync_s must be a number of seconds ≥ 0"):
            RecorderConfig(tmp_path / "ep", fsync_s=bad)
