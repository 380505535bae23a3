"""Recorder fsyncs: every stream synced on the `fsync_s` cadence on the writer thread (counted through a
wrapper of os.fsync), each new directory entry once, a failed fsync a writer error, the scene setting — and
the whole live path: simulated devices → adapters → rig clock → recorder → episode reader."""
from __future__ import annotations

import errno
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from helpers.simulated_rig import frame_picture, simulated_rig, synthetic_snapshot
from touchanything.app.sessions.scene import read_scene
from touchanything.core.errors import UserError
from touchanything.core.snapshot import FPS, Snapshot
from touchanything.core.temporary_files import temporary_path
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_streams import IDENTITY_WXYZ
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.hardware.threaded_source import now_us
from touchanything.devices.rig.recorder import Recorder, RecorderConfig
from touchanything.devices.rig.rig_clock import RigClock


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
        began = time.monotonic()
        with clock:
            time.sleep(2.0)
            clock.unsubscribe(recorder.write)
            written_ticks = len(snapshots)
            ran_s = time.monotonic() - began  # about 2 s; more where a busy CPU wakes the sleeper late
            live_status = recorder.status()
        counters = recorder.stop()
    assert live_status.startswith(f"recording {folder}:")
    synced = {f.thread for f in fsyncs if f.path.is_relative_to(folder.resolve())}
    assert synced == {"recorder"}  # the writer thread's work, never the rig clock's
    assert counters.dropped == 0 and counters.written == written_ticks
    assert 0.75 * 30 * ran_s <= written_ticks <= 30 * ran_s + 1, (written_ticks, ran_s)  # the 30 Hz clock's ticks
    recorded = snapshots[:written_ticks]
    with open_episode(folder) as episode:
        assert episode.num_frames == written_ticks and episode.view_names == ("ego",)
        assert np.array_equal(episode.glove.timestamps_us, [s.t_us for s in recorded])
        assert episode.glove.timestamps_us[0] >= started_us
        last_ego = None
        for k, s in enumerate(recorded):
            # A source stale on a tick (a busy CPU can hold its reader back > 200 ms) is absent from that Snapshot
            # and recorded absent: a null glove (read back with the identity quaternion), no mocap or tracker row,
            # the video's last image again.
            present = s.glove_present
            assert np.array_equal(episode.glove.present[k], present)
            assert np.array_equal(episode.glove.raw[k], s.pressure_raw)
            assert np.array_equal(episode.glove.quat_wxyz[k][present], s.imu_wxyz[present])
            assert np.array_equal(episode.glove.quat_wxyz[k][~present], np.tile(IDENTITY_WXYZ, (int((~present).sum()), 1)))
            assert np.array_equal(episode.wilor.joints[k], s.joints.reshape(2, 21, 3))
            assert np.array_equal(episode.wilor.valid[k], s.joints_valid)
            if s.mocap_joints is None:
                assert not episode.rokoko.valid[k].any()
            else:
                assert np.array_equal(episode.rokoko.joints[k], s.mocap_joints.reshape(2, 21, 3))
            if "chest" in s.trackers:
                assert np.array_equal(episode.trackers.poses[k, 0], s.trackers["chest"])
            else:
                assert not episode.trackers.valid[k, 0]
            last_ego = s.images.get("ego", last_ego)
            if last_ego is not None:
                assert np.abs(episode.views["ego"].read(k).astype(int) - last_ego).mean() < 8
        assert episode.pressure.grids.shape == (written_ticks, 2, 21, 21)


def streaming(folder: Path, name: str) -> Path:
    """Where stream `name` is written until the recording ends (renamed into place then)."""
    return temporary_path(folder / name)


def test_sync_fsyncs_every_file_and_each_new_directory_entry_once(tmp_path, fsyncs):
    folder = (tmp_path / "Lab" / "task" / "take").resolve()
    hands_file, video, glove_file = (streaming(folder, n) for n in ("wilor_hands.json", "chest.mp4", "jq_pressure.json"))
    writer = RawEpisodeWriter(folder, durable=True)
    hands = (np.zeros((2, 21, 3), np.float32), np.array([True, True]))
    writer.write(EpisodeFrame(images={"ego": frame_picture(0)}, wilor=hands))
    writer.sync()  # the files, then the new folders' entries from the outside in, then the folder's new files
    assert not video.exists()  # FFmpeg creates it with x264's first packet, frames later
    assert [f.path for f in fsyncs] == [hands_file, tmp_path.resolve(), folder.parents[1], folder.parent, folder]
    assert fsyncs[0].size == len(hands_file.read_bytes()) > 0
    fsyncs.clear()
    for k in range(1, 40):
        writer.write(EpisodeFrame(images={"ego": frame_picture(k)}, wilor=hands))
    writer.sync()  # the video's file now exists: it, and the folder again for its entry
    assert [f.path for f in fsyncs] == [video, hands_file, folder]
    fsyncs.clear()
    writer.write(EpisodeFrame(images={"ego": frame_picture(40)}, wilor=hands))
    writer.sync()  # no new file: no directory
    assert [f.path for f in fsyncs] == [video, hands_file]
    fsyncs.clear()
    glove = (np.ones((2, 256), np.uint8), np.array([True, True]), np.zeros((2, 4), np.float32))
    writer.write(EpisodeFrame(images={"ego": frame_picture(41)}, wilor=hands, glove=glove))
    writer.sync()  # a new stream: the folder again
    assert [f.path for f in fsyncs] == [video, hands_file, glove_file, folder]
    fsyncs.clear()
    writer.close()  # each file after its last bytes, the folder after their renames, the grids before theirs, the folder
    assert [f.path for f in fsyncs] == [video, hands_file, glove_file, folder,
                                        temporary_path(folder / "pressure_grids.npz"), folder]
    assert fsyncs[0].size == (folder / "chest.mp4").stat().st_size
    fsyncs.clear()
    with RawEpisodeWriter(tmp_path / "plain") as plain:  # not durable: only the grids, written under the output rule
        plain.write(EpisodeFrame(images={"ego": frame_picture(0)}, wilor=hands, glove=glove))
    assert [f.path for f in fsyncs] == [temporary_path(tmp_path / "plain" / "pressure_grids.npz"), tmp_path / "plain"]


def sync_rounds(fsyncs: list[Fsync], folder: Path) -> list[float]:
    """When each sync round synced wilor_hands.json (every synthetic frame has a row in it; chest.mp4 only
    exists from x264's first packet on)."""
    return [f.t for f in fsyncs if f.path == streaming(folder, "wilor_hands.json")]


def test_the_recorder_fsyncs_every_stream_on_its_cadence_on_the_writer_thread(tmp_path, fsyncs):
    folder = (tmp_path / "ep").resolve()
    recorder = Recorder(RecorderConfig(folder, fsync_s=0.5))
    began = time.monotonic()  # before start(): the recorder's first period begins inside it
    recorder.start()
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
        assert len([f for f in during if f.path == streaming(folder, name)]) == len(rounds)
    assert 1 <= len([f for f in during if f.path == streaming(folder, "vive_poses.json")]) <= len(rounds)  # frame 10 on
    # stop(): every file once more, after its last bytes, and the grids
    last = {f.path.name: f.size for f in fsyncs[len(during):]}
    assert all(last[streaming(folder, name).name] == (folder / name).stat().st_size for name in
               ("chest.mp4", "wilor_hands.json", "jq_pressure.json", "vive_poses.json"))
    assert temporary_path(folder / "pressure_grids.npz").name in last and folder.name in last


def wait_until(condition, what: str, timeout_s: float = 20.0) -> None:
    """A hang guard, not a measurement: poll `condition` until it holds."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"{what} did not happen within {timeout_s} s"
        time.sleep(0.01)


def test_the_recorder_syncs_what_waits_even_when_no_frame_comes(tmp_path, fsyncs):
    folder = (tmp_path / "ep").resolve()
    hands_file = streaming(folder, "wilor_hands.json")
    recorder = Recorder(RecorderConfig(folder, fsync_s=0.3))
    recorder.start()
    for k in range(3):
        recorder.write(synthetic_snapshot(k))
    wait_until(lambda: recorder.counters.written == 3, "writing 3 frames")
    size = hands_file.stat().st_size
    # no further frame comes: the rows written are synced all the same, once the period is over
    wait_until(lambda: any(f.path == hands_file and f.size == size for f in list(fsyncs)), "a sync of all 3 rows")
    time.sleep(4 * 0.3)  # four more periods with nothing new
    idle = list(fsyncs)
    recorder.stop()
    hands = [f.size for f in idle if f.path == hands_file]  # one per sync round
    assert hands.count(size) == 1 and hands[-1] == size, hands  # no round again while nothing was new
    assert 1 <= len(hands) <= 3  # a round per frame at most, however slowly they were written


def test_the_first_period_starts_with_start_not_with_a_late_writer_thread(tmp_path, fsyncs, monkeypatch):
    """On a busy CPU the writer thread may start late while frames queue: their first sync still falls due
    `fsync_s` after start(), not `fsync_s` after the thread began."""
    run = Recorder._run

    def late_run(self, *args) -> None:
        time.sleep(1.2)
        run(self, *args)

    monkeypatch.setattr(Recorder, "_run", late_run)
    folder = (tmp_path / "ep").resolve()
    recorder = Recorder(RecorderConfig(folder, fsync_s=0.8))
    began = time.monotonic()
    recorder.start()
    for k in range(3):
        recorder.write(synthetic_snapshot(k))
    wait_until(lambda: sync_rounds(list(fsyncs), folder), "a first sync")
    recorder.stop()
    first = sync_rounds(fsyncs, folder)[0] - began
    # due at 0.8 s, so done as soon as the late thread has written a frame (1.2 s + the write); counted from
    # the thread's own start it would wait until 1.2 + 0.8 = 2.0 s
    assert 1.2 <= first < 2.0 - 0.05, first


@pytest.mark.parametrize("fsync_s, rounds", [(0, 6), (None, 0)])
def test_fsync_after_every_frame_or_never(tmp_path, fsyncs, fsync_s, rounds):
    folder = (tmp_path / "ep").resolve()
    with Recorder(RecorderConfig(folder, fsync_s=fsync_s)) as recorder:
        for k in range(6):
            recorder.write(synthetic_snapshot(k))
    assert recorder.counters.written == 6
    close = 1 if fsync_s is not None else 0  # stop() syncs once more, unless never
    assert len(sync_rounds(fsyncs, folder)) == rounds + close
    assert len([f for f in fsyncs if f.path == streaming(folder, "jq_pressure.json")]) == rounds + close


def test_a_failed_fsync_is_a_writer_error(tmp_path, monkeypatch):
    def failing_fsync(fd: int) -> None:
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    monkeypatch.setattr(os, "fsync", failing_fsync)  # the disk fails
    folder = tmp_path / "ep"
    recorder = Recorder(RecorderConfig(folder, fsync_s=0))
    recorder.start()
    for k in range(6):
        recorder.write(synthetic_snapshot(k))
    with pytest.raises(UserError, match=r"failed: Input/output error \(.*/ep/wilor_hands.json\); 1 of the 1 frames"):
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
