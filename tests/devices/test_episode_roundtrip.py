"""Write → read round trips for every file of a raw EgoTouch episode."""
from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.episode_files import write_masks, write_quality
from tests.conftest import frame_image, glove_sample, wilor_hands, write_episode
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_files import (
    Masks,
    read_camera_matrices,
    read_masks,
    read_pressure_grids,
    read_quality,
    write_camera_matrices,
    write_pressure_grids,
)
from touchanything.devices.episodes.episode_loader import find_raw_episodes, open_episode
from touchanything.devices.episodes.episode_streams import read_glove, read_hands, read_trackers
from touchanything.devices.episodes.raw_episode import open_raw_episode
from touchanything.devices.episodes.video_io import VideoReader, VideoWriter
from touchanything.devices.tactile_pipeline import process_raw


def test_written_episode_reads_back(episode_dir):
    with open_raw_episode(episode_dir) as ep:
        assert ep.num_frames == 40 and ep.problems == []
        assert ep.view_names == ("ego", "wrist_left", "wrist_right")
        assert (ep.scene, ep.task, ep.trajectory_id) == ("Home", "pick_up_bottle", "20260319_211038_740")
        assert ep.timestamps_us[1] == 33333
        rng = np.random.default_rng(0)
        for i in range(40):
            joints, valid = wilor_hands(i, rng)
            rng.normal(0, 0.1, size=(2, 21, 3))  # rokoko draw
            raw = glove_sample(i, rng)
            rng.normal(0, 1, size=(3, 7))  # trackers draw
            assert np.array_equal(ep.wilor.valid[i], valid)
            assert np.array_equal(ep.wilor.joints[i][valid], joints[valid])
            assert np.all(ep.wilor.joints[i][~valid] == 0)
            assert np.array_equal(ep.glove.raw[i], raw)
        assert ep.trackers.valid[:, 2].sum() == 32
        assert np.array_equal(ep.pressure.grids, process_raw(ep.glove.raw, TactileLayout.default()).grids, equal_nan=True)
        for k, view in enumerate(ep.view_names):
            for i in (0, 17, 39):
                decoded = ep.views[view].read(i).astype(int)
                assert np.abs(decoded - frame_image(k, i, (48, 64))).mean() < 8.0


def test_video_random_access_equals_sequential(tmp_path):
    path = tmp_path / "v.mp4"
    with VideoWriter(path) as writer:
        for i in range(100):
            writer.write(frame_image(0, i, (48, 64)))
    with VideoReader(path) as reader:
        assert reader.num_frames == 100 and (reader.width, reader.height) == (64, 48)
        sequential = list(reader.frames())
    assert len(sequential) == 100
    with VideoReader(path) as reader:
        for i in (99, 3, 50, 51, 0, 75, 20):
            assert np.array_equal(reader.read(i), sequential[i])
        assert reader.read(100) is None and reader.read(-1) is None


def test_pressure_grids_npz_round_trip(tmp_path):
    grids = np.random.default_rng(0).random((5, 2, 21, 21)).astype(np.float32)
    grids[:, :, 0, :] = np.nan
    path = tmp_path / "pressure_grids.npz"
    write_pressure_grids(path, grids, np.array([True, False]), np.array([100.0, 90.0]), np.array([30.0, 40.0]))
    back = read_pressure_grids(path)
    assert np.array_equal(back.grids, grids, equal_nan=True)
    assert back.attrs["separate_normalization"] and back.attrs["tactile_max_right"] == 90.0
    assert back.attrs["bend_max_left"] == 30.0 and back.attrs["num_frames"] == 5
    assert back.attrs["baseline_corrected_left"] and not back.attrs["baseline_corrected_right"]
    with np.load(path) as raw:  # the official key names
        assert raw["left_pressure_grid"].shape == (5, 21, 21) and int(raw["grid_size"]) == 21


def test_masks_quality_and_camera_matrix_round_trip(tmp_path):
    masks = Masks(np.ones((3, 2, 4, 5), np.uint8), np.arange(6, dtype=np.int32).reshape(3, 2), np.array([1, 0, 1], bool))
    write_masks(tmp_path / "masks.npz", masks)
    back = read_masks(tmp_path / "masks.npz")
    assert np.array_equal(back.masks, masks.masks) and np.array_equal(back.obj_ids, masks.obj_ids)
    assert np.array_equal(back.valid_frames, masks.valid_frames)
    write_quality(tmp_path / "q.json", {"left": 0.5, "right": 0.0})
    assert read_quality(tmp_path / "q.json") == {"left": 0.5, "right": 0.0}
    assert json.loads((tmp_path / "q.json").read_text())["duplicate_frames"]["left"]["ratio"] == 0.5
    cams = {"chest": np.diag([500.0, 501.0, 1.0]), "left": np.array([[300, 0, 320], [0, 300, 240], [0, 0, 1.0]])}
    write_camera_matrices(tmp_path / "camera_matrix.txt", cams)
    back = read_camera_matrices(tmp_path / "camera_matrix.txt")
    assert set(back) == {"chest", "left"} and np.array_equal(back["left"], cams["left"])
    np.savetxt(tmp_path / "plain.txt", cams["chest"])  # a bare 3×3 is the chest camera
    assert np.array_equal(read_camera_matrices(tmp_path / "plain.txt")["chest"], cams["chest"])


def test_stream_readers_round_trip(episode_dir):
    hands, problems = read_hands(episode_dir / "wilor_hands.json")
    assert problems == [] and hands.joints.shape == (40, 2, 21, 3)
    trackers, problems = read_trackers(episode_dir / "vive_poses.json")
    assert problems == [] and trackers.poses.shape == (40, 3, 7)
    glove, problems = read_glove(episode_dir / "jq_pressure.json")
    assert problems == [] and glove.present.all() and glove.timestamps_us[2] == 66666
    assert np.allclose(glove.quat_wxyz[..., 0], 1.0)


def test_streams_appearing_later_keep_line_numbers(tmp_path):
    from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter

    rng = np.random.default_rng(3)
    with RawEpisodeWriter(tmp_path / "ep") as writer:
        for i in range(6):
            frame = EpisodeFrame(images={"ego": frame_image(0, i, (32, 32))})
            if i >= 2:
                frame.wilor = wilor_hands(i, rng)
            writer.write(frame)
    hands, _ = read_hands(tmp_path / "ep" / "wilor_hands.json")
    assert len(hands.valid) == 6 and not hands.valid[:2].any() and hands.valid[2:, 0].all()


def test_discovery_finds_trajectories_up_to_four_levels(tmp_path):
    for name in ("Home/a/1", "Office/b/2"):
        write_episode(tmp_path / name, frames=3, size=(16, 16))
    (tmp_path / "Home" / "notes").mkdir()
    assert [p.relative_to(tmp_path).as_posix() for p in find_raw_episodes(tmp_path)] == ["Home/a/1", "Office/b/2"]
    assert find_raw_episodes(tmp_path / "Home" / "a" / "1") == [tmp_path / "Home" / "a" / "1"]


def test_open_episode_rejects_other_paths(tmp_path):
    from touchanything.core.errors import DataError

    (tmp_path / "x.txt").write_text("hi")
    for path, message in ((tmp_path / "x.txt", "not an episode"), (tmp_path, "not an episode folder"),
                          (tmp_path / "nope", "not found")):
        with pytest.raises(DataError, match=message):
            open_episode(path)
