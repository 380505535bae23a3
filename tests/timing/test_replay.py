"""Replay source: Snapshots from raw folders and HDF5, real-time pacing without drift, seek, loop, subsets."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource


def test_fast_replay_yields_every_frame_as_snapshots(episode_dir):
    with open_episode(episode_dir) as ep:
        snaps = list(ReplaySource(ep, ReplayConfig(speed=None)))
        assert [s.frame_index for s in snaps] == list(range(40))
        s = snaps[3]
        assert set(s.images) == {"ego", "wrist_left", "wrist_right"}
        assert s.images["ego"].shape == (48, 64, 3) and s.images["ego"].dtype == np.uint8
        assert s.joints.shape == (42, 3) and s.joints.dtype == np.float32
        assert np.array_equal(s.joints[:21], ep.wilor.joints[3, 0]) and np.array_equal(s.joints_valid, ep.wilor.valid[3])
        assert not s.joints_valid[1] and np.all(s.joints[21:] == 0)  # the right hand vanishes on frame 3
        assert s.pressure_raw.shape == (2, 256) and s.pressure_grid.shape == (2, 21, 21)
        assert s.imu_wxyz.shape == (2, 4)
        assert set(s.trackers) == {"chest", "left_wrist", "right_wrist"}
        assert "right_wrist" not in snaps[5].trackers
        assert all(b.t_us >= a.t_us for a, b in zip(snaps, snaps[1:]))


def test_real_time_pacing_has_no_drift(episode_dir):
    with open_episode(episode_dir) as ep:
        source = ReplaySource(ep, ReplayConfig(speed=1.0))
        start = time.monotonic()
        times = [(s.t_us / 1e6) for s in source]
        elapsed = time.monotonic() - start
    # frame k leaves at the first one's due time + k / 30 s, never sooner; later by the last frame's wake-up only
    assert 39 / 30 - 0.01 <= elapsed < 39 / 30 + 0.25, elapsed
    lateness = np.array(times) - np.arange(40) / 30
    lateness -= np.median(lateness)
    assert np.median(np.abs(lateness)) < 0.01  # frames leave on their schedule
    # a scheduling stall on a busy machine may delay a few frames; drift would move them all
    assert abs(np.median(lateness[-10:]) - np.median(lateness[:10])) < 0.03  # no accumulating drift


def test_speed_factor_and_a_slow_consumer_catch_up_on_schedule(episode_dir):
    with open_episode(episode_dir) as ep:
        source = ReplaySource(ep, ReplayConfig(speed=2.0))
        start = time.monotonic()
        for s in source:
            if s.frame_index == 5:
                time.sleep(0.3)  # a consumer hiccup: later frames are released at once until on schedule
        elapsed = time.monotonic() - start
    # on the 2× schedule, never sooner; not caught up, the hiccup would add its 0.3 s
    assert 39 / 60 - 0.01 <= elapsed < 39 / 60 + 0.2, elapsed


def test_seek_loop_views_and_pose_source(episode_dir):
    with open_episode(episode_dir) as ep:
        config = ReplayConfig(speed=None, loop=True, views=("ego",), pose_source="rokoko", start_frame=35)
        source = ReplaySource(ep, config)
        indices = []
        for s in source:
            indices.append(s.frame_index)
            assert set(s.images) == {"ego"} and s.source_status["pose"] == "rokoko"
            assert np.array_equal(s.joints[21:], ep.rokoko.joints[s.frame_index, 1])
            if len(indices) == 8:
                source.seek(20)
            if len(indices) == 12:
                break
        assert indices == [35, 36, 37, 38, 39, 0, 1, 2, 20, 21, 22, 23]


def test_seek_from_another_thread(episode_dir):
    with open_episode(episode_dir) as ep:
        source = ReplaySource(ep, ReplayConfig(speed=4.0))
        seen = []
        threading.Timer(0.1, source.seek, args=(30,)).start()
        for s in source:
            seen.append(s.frame_index)
        assert 30 in seen and seen[-1] == 39 and len(seen) < 40


def test_player_controls_pause_step_speed_and_hold_at_end(episode_dir):
    """Transport controls from another thread: a paused player releases nothing until a step (exactly one
    frame per step), resumes on schedule at a new speed, holds at the end and restarts on play."""
    with open_episode(episode_dir) as ep:
        source = ReplaySource(ep, ReplayConfig(speed=1.0, hold_at_end=True))
        seen: list[int] = []
        player = threading.Thread(target=lambda: seen.extend(s.frame_index for s in source))
        source.pause()
        player.start()
        time.sleep(0.3)
        assert seen == []
        for _ in range(3):
            source.step()
        deadline = time.monotonic() + 5
        while len(seen) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.2)
        assert seen == [0, 1, 2]
        source.set_speed(8.0)
        started = time.monotonic()
        source.resume()
        while len(seen) < 40 and time.monotonic() < deadline + 5:
            time.sleep(0.01)
        assert seen == list(range(40)) and time.monotonic() - started < 1.0  # 37 frames at 8× ≈ 0.15 s
        time.sleep(0.2)
        assert source.paused and player.is_alive() and len(seen) == 40
        source.resume()
        while len(seen) < 45 and time.monotonic() < deadline + 10:
            time.sleep(0.01)
        assert seen[40:45] == [0, 1, 2, 3, 4]
        source.close()
        player.join(5)
        assert not player.is_alive()
        with pytest.raises(UserError, match="speed"):
            source.set_speed(0.0)


def test_replay_from_hdf5_equals_replay_from_raw(episode_dir, tmp_path):
    convert_trajectory(episode_dir, tmp_path / "e.hdf5")
    with open_episode(episode_dir) as raw, open_episode(tmp_path / "e.hdf5") as h5:
        for a, b in zip(ReplaySource(raw, ReplayConfig(speed=None)), ReplaySource(h5, ReplayConfig(speed=None))):
            assert a.frame_index == b.frame_index
            assert np.array_equal(a.images["wrist_left"], b.images["wrist_left"])
            assert np.array_equal(a.joints, b.joints) and np.array_equal(a.joints_valid, b.joints_valid)
            assert np.array_equal(a.pressure_grid, b.pressure_grid, equal_nan=True)
        assert h5.glove is None


def test_missing_view_is_reported_in_status(episode_dir):
    (episode_dir / "right.mp4").unlink()
    with open_episode(episode_dir) as ep:
        s = next(iter(ReplaySource(ep, ReplayConfig(speed=None))))
        assert s.source_status["wrist_right"] == "absent" and "wrist_right" not in s.images


@pytest.mark.parametrize("config, message", [
    (ReplayConfig(views=("ego", "top")), "unknown view"),
    (ReplayConfig(pose_source="hamer"), "unknown pose source"),
    (ReplayConfig(speed=0.0), "positive"),
    (ReplayConfig(speed=float("nan")), "positive"),
    (ReplayConfig(start_frame=400), "outside the episode"),
])
def test_bad_replay_options(episode_dir, config, message):
    with open_episode(episode_dir) as ep, pytest.raises(UserError, match=message):
        ReplaySource(ep, config)
