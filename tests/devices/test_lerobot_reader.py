"""The LeRobot reader (`devices/episodes/lerobot_episode.py`) at its edges: another
dataset's joints and trackers read by shape with and without validity flags, frame times from the frame rate, the
frame-rate bounds, unreadable metadata named, and an episode's frames kept within its part of a shared video."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from conftest import frame_image, write_episode
from helpers.lerobot_community import write_community_dataset
from touchanything.core.errors import DataError
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.lerobot_episode import read_info
from touchanything.devices.episodes.lerobot_export import export_lerobot
from touchanything.devices.episodes.video_io import VideoWriter

T = 6


def _hands_and_trackers() -> tuple[np.ndarray, np.ndarray]:
    """(T, 2, 21, 3) joints [left, right] and (T, 3, 7) tracker poses: the left hand absent (zeros) on frame 1 and
    out of the official bounds (|x| ≤ 1000: x = 1500) on frame 2, the right hand absent on frame 4; the second tracker absent
    (zeros) on frames 0 and 3."""
    rng = np.random.default_rng(4)
    joints = rng.uniform(-2, 2, (T, 2, 21, 3)).astype(np.float32)
    joints[..., 2] += 50
    joints[1, 0], joints[4, 1] = 0.0, 0.0
    joints[2, 0, :, 0] = 1500.0
    poses = rng.uniform(0.5, 2.0, (T, 3, 7)).astype(np.float32)
    poses[[0, 3], 1] = 0.0
    return joints, poses


def _foreign_dataset(root: Path, flags: bool, tasks: list[str]) -> Path:
    """One community-layout episode (v2.0, hand order not stated: [right, left] on disk) at 2 frames/s with joints
    (2, 21, 3) and trackers (3, 7) under this project's old names, no `timestamp` column, the episode's `tasks` as
    given and, with
    `flags`, validity columns that say the right hand was not seen on frame 0 and the first tracker not on frame 5.
    Its rows are stored in reverse frame order; its head camera is listed last, after a video named `depth`."""
    joints, poses = _hands_and_trackers()
    grid = np.where(TactileLayout.default().valid, 0.5, np.nan).astype(np.float32)
    write_community_dataset(root, [np.repeat(grid[None], T, axis=0)], [np.zeros((T, 32, 48, 3), np.uint8)])
    path = root / "data" / "chunk-000" / "episode_000000.parquet"
    table = pq.read_table(path).drop_columns(["timestamp"])
    columns = {fmt.JOINTS: pa.FixedSizeListArray.from_arrays(pa.array(joints[:, ::-1].reshape(-1)), 2 * 21 * 3),
               fmt.TRACKERS: pa.FixedSizeListArray.from_arrays(pa.array(poses.reshape(-1)), 21)}
    if flags:
        seen = np.ones((T, 2), bool)
        seen[0, 0] = False  # on disk [right, left]: the right hand
        located = np.ones((T, 3), bool)
        located[5, 0] = False
        columns[fmt.JOINTS_VALID] = pa.FixedSizeListArray.from_arrays(pa.array(seen.reshape(-1)), 2)
        columns[fmt.TRACKERS_VALID] = pa.FixedSizeListArray.from_arrays(pa.array(located.reshape(-1)), 3)
    for name, column in columns.items():
        table = table.append_column(name, column)
    pq.write_table(table.take(np.arange(T)[::-1]), path)  # rows in reverse frame order: read back sorted
    info = json.loads((root / "meta" / "info.json").read_text())
    del info["features"]["timestamp"]
    info["fps"] = 2  # frame i at i / 2 s
    info["features"][fmt.JOINTS] = {"dtype": "float32", "shape": [2, 21, 3], "names": None}
    info["features"][fmt.TRACKERS] = {"dtype": "float32", "shape": [3, 7], "names": None}
    video = info["features"].pop("observation.images.main")  # the head camera listed after the numeric features,
    info["features"]["depth"] = dict(video)  # behind a video that is no camera of ours (a name without dots)
    info["features"]["observation.images.main"] = video
    (root / "meta" / "info.json").write_text(json.dumps(info))
    (root / "meta" / "episodes.jsonl").write_text(json.dumps({"episode_index": 0, "tasks": tasks, "length": T}) + "\n")
    return root


def test_another_dataset_s_hands_and_trackers_without_flags_are_valid_where_seen_and_in_bounds(tmp_path):
    root = _foreign_dataset(tmp_path / "foreign", flags=False, tasks=["wipe the table", "then dry it"])
    joints, poses = _hands_and_trackers()
    with open_episode(root / "episode_000000") as episode:
        # left absent on 1 and out of bounds on 2, right absent on 4
        assert episode.wilor.valid.tolist() == [[True, True], [False, True], [False, True], [True, True], [True, False], [True, True]]
        np.testing.assert_array_equal(episode.wilor.joints[0], joints[0])  # [right, left] on disk, [left, right] here
        assert not episode.wilor.joints[2, 0].any() and not episode.wilor.joints[4, 1].any()
        np.testing.assert_array_equal(episode.trackers.poses, poses)
        assert episode.trackers.valid.tolist() == [[True, False, True], [True] * 3, [True] * 3, [True, False, True], [True] * 3, [True] * 3]
        # no timestamp column: frame i at i / fps s, in microseconds
        assert episode.timestamps_us.tolist() == [0, 500_000, 1_000_000, 1_500_000, 2_000_000, 2_500_000]
        assert episode.task == "wipe the table"
        assert any("no hand order in its names; read as [right, left]" in p for p in episode.problems)
        assert episode.view_names == ("ego",)
        assert any("depth: video feature not read" in p for p in episode.problems)


def test_another_dataset_s_validity_flags_are_taken_as_they_are(tmp_path):
    root = _foreign_dataset(tmp_path / "foreign", flags=True, tasks=["wipe the table"])
    with open_episode(root / "episode_000000") as episode:
        # the flags, not the joints, decide: the right hand unseen on frame 0 although its joints are there; frame 2's
        # left hand seen although out of bounds, frame 1's although zero
        assert episode.wilor.valid.tolist() == [[True, False]] + [[True, True]] * 5
        assert not episode.wilor.joints[0, 1].any() and episode.wilor.joints[0, 0].any()
        assert episode.trackers.valid.tolist() == [[True] * 3] * 5 + [[False, True, True]]


def test_the_frame_rate_must_lie_in_0_to_1000_and_the_metadata_name_its_features(tmp_path):
    info_path = tmp_path / "meta" / "info.json"
    info_path.parent.mkdir(parents=True)
    for fps, accepted in ((1000, True), (0.5, True), (1000.5, False), (0, False), (-30, False)):
        info_path.write_text(json.dumps({"features": {}, "fps": fps}))
        if accepted:
            assert read_info(tmp_path)["fps"] == fps
        else:
            with pytest.raises(DataError, match="is not a frame rate"):
                read_info(tmp_path)
    info_path.write_text(json.dumps({"fps": 30}))
    with pytest.raises(DataError, match="not a LeRobot info.json"):
        read_info(tmp_path)


def test_unreadable_episode_metadata_and_a_missing_data_file_are_named(tmp_path):
    out = tmp_path / "lerobot"
    write_episode(tmp_path / "raw" / "Home" / "pick" / "001", frames=4)
    export_lerobot(tmp_path / "raw", out)
    data = out / "data" / "chunk-000" / "file-000.parquet"
    data.rename(data.with_suffix(".moved"))
    with pytest.raises(DataError, match="file-000.parquet.*file not found"):
        open_episode(out / "episode_000000")
    data.with_suffix(".moved").rename(data)
    (out / "meta" / "episodes" / "chunk-000" / "file-001.parquet").mkdir()  # not a file
    with pytest.raises(DataError, match="file-001.parquet.*not a readable parquet file"):
        open_episode(out / "episode_000000")
    community = write_community_dataset(tmp_path / "community", [np.zeros((3, 2, 21, 21), np.float32)],
                                        [np.zeros((3, 32, 48, 3), np.uint8)])
    (community / "meta" / "episodes.jsonl").write_bytes(b'{"episode_index": 0, "tasks": ["\xff\xfe"]}\n')
    with pytest.raises(DataError, match="episodes.jsonl.*not readable JSON lines"):
        open_episode(community / "episode_000000")
    (community / "meta" / "episodes.jsonl").write_text('{"episode_index": 0}\n["a list"]\n{"length": 3}\n')
    with open_episode(community / "episode_000000") as episode:  # lines that are no episode row are passed over
        assert episode.num_frames == 3


def test_an_episode_s_frames_end_where_its_part_of_the_video_ends(tmp_path):
    """Two episodes in one video file: the second's frame −1 and frame 3 (it has 3) are not the first's or the next
    file frame; and an export whose state names differ from this project's is named with the names it expects."""
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick" / "001", frames=4, seed=1)
    write_episode(root / "Home" / "pick" / "002", frames=3, seed=2)
    out = tmp_path / "lerobot"
    export_lerobot(root, out)
    with open_episode(out / "episode_000001") as episode:
        assert episode.views["ego"].read(-1) is None and episode.views["ego"].read(3) is None
        assert episode.views["ego"].read(0) is not None
    with open_episode(out / "episode_000000") as episode:  # its frame 4 would be the file's next episode's frame 0
        assert episode.views["ego"].read(3) is not None and episode.views["ego"].read(4) is None
    with pytest.raises(DataError, match=r"episode_000002.*no such episode \(the dataset has 2: episode_000000 … episode_000001\)"):
        open_episode(out / "episode_000002")
    info = json.loads((out / "meta" / "info.json").read_text())
    info["features"][fmt.STATE]["names"] = [f"value{i}" for i in range(128)]
    (out / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(DataError, match=r"observation.state names.*not the 128 names this project exports \(left.wrist.x … right.seen\)"):
        open_episode(out / "episode_000000")


def test_a_feature_the_data_lacks_a_missing_video_and_an_empty_dataset_are_named_not_fatal(tmp_path):
    root = tmp_path / "raw"
    write_episode(root / "Home" / "pick" / "001", frames=4)
    out = tmp_path / "lerobot"
    export_lerobot(root, out)
    data = out / "data" / "chunk-000" / "file-000.parquet"
    pq.write_table(pq.read_table(data).drop_columns([fmt.TRACKERS]), data)  # info.json still names it
    (out / "videos" / fmt.VIEW_FEATURES["wrist_right"] / "chunk-000" / "file-000.mp4").unlink()
    short = out / "videos" / fmt.VIEW_FEATURES["wrist_left"] / "chunk-000" / "file-000.mp4"
    short.unlink()  # a writer never opens an existing file
    with VideoWriter(short, 30, 10, fragmented=False) as writer:  # 2 of the episode's 4 frames
        for i in range(2):
            writer.write(frame_image(1, i, (48, 64)))
    info = json.loads((out / "meta" / "info.json").read_text())
    info["features"]["observation.images.head"] = info["features"][fmt.VIEW_FEATURES["ego"]]  # a second head camera
    (out / "meta" / "info.json").write_text(json.dumps(info))
    with open_episode(out / "episode_000000") as episode:
        assert episode.trackers is None and episode.wilor is not None
        assert episode.view_names == ("ego", "wrist_left")
        assert any("file-000.mp4" in p and fmt.VIEW_FEATURES["wrist_right"] in p for p in episode.problems)
        assert any("observation.images.head" in p and "video feature not read" in p for p in episode.problems)
        assert any("holds 2 frames, the episode needs 4" in p for p in episode.problems)
        assert episode.views["wrist_left"].read(1) is not None and episode.views["wrist_left"].read(2) is None
    empty = write_community_dataset(tmp_path / "empty", [np.zeros((3, 2, 21, 21), np.float32)], [np.zeros((3, 32, 48, 3), np.uint8)])
    (empty / "meta" / "episodes.jsonl").write_text("")
    with pytest.raises(DataError, match=r"no such episode \(the dataset has 0: episode_000000 … episode_000000\)"):
        open_episode(empty / "episode_000000")


def test_a_v2_dataset_without_the_community_head_camera_or_episode_rows(tmp_path):
    """Without `observation.images.main` a v2.x dataset is not taken for the community conversion: an unstated hand
    order is read as the official [left, right] (and said); without meta/episodes.jsonl and total_episodes it has
    no episode."""
    rng = np.random.default_rng(1)
    grids = [np.where(TactileLayout.default().valid, rng.random((4, 2, 21, 21)), np.nan).astype(np.float32)]
    root = write_community_dataset(tmp_path / "other", grids, [np.zeros((4, 32, 48, 3), np.uint8)])
    (root / "videos" / "chunk-000" / "observation.images.main").rename(root / "videos" / "chunk-000" / "observation.images.ego")
    info = json.loads((root / "meta" / "info.json").read_text())
    info["features"]["observation.images.ego"] = info["features"].pop("observation.images.main")
    (root / "meta" / "info.json").write_text(json.dumps(info))
    with open_episode(root / "episode_000000") as episode:
        np.testing.assert_array_equal(episode.pressure.grids, grids[0][:, ::-1])  # as stored: [right, left]
        assert any("no hand order in its names; read as [left, right]" in p for p in episode.problems)
        assert episode.view_names == ("ego",)
    (root / "meta" / "episodes.jsonl").unlink()
    del info["total_episodes"]
    (root / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(DataError, match="the dataset has 0"):
        open_episode(root / "episode_000000")
