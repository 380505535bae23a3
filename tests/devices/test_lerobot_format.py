"""The LeRobot format's shared facts (`devices/episodes/lerobot_format.py`) at their edges:
tactile value names within the 21×21 grid, episode addresses only under a dataset root, and the file limits and
feature descriptions info.json carries, by value."""
from __future__ import annotations

import json

import numpy as np

from conftest import write_episode
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.lerobot_export import export_lerobot


def test_tactile_names_are_cells_of_the_21_by_21_grid():
    hand, row, column = fmt.cells_of(["left.r00c00", "right.r20c20", "left.r05c17"])
    assert hand.tolist() == [0, 1, 0] and row.tolist() == [0, 20, 5] and column.tolist() == [0, 20, 17]
    for outside in ("left.r21c05", "left.r05c21", "right.r21c21", "middle.r01c01", "left.r1c1"):
        assert fmt.cells_of(["left.r00c00", outside]) is None, outside
    assert fmt.cells_of([]) is None and fmt.cells_of("left.r00c00") is None and fmt.cells_of([3]) is None


def test_an_episode_address_is_one_only_under_a_dataset_root(tmp_path):
    assert fmt.parse_address(tmp_path / "episode_000001") is None  # no meta/info.json beside it
    (tmp_path / "meta").mkdir()
    (tmp_path / "meta" / "info.json").write_text("{}")
    assert fmt.parse_address(tmp_path / "episode_000001") == (tmp_path, 1)
    assert fmt.parse_address(tmp_path / "episode_1") is None and fmt.parse_address(tmp_path / "file-000") is None


def test_info_json_carries_lerobot_s_file_limits_and_the_features_descriptions(tmp_path):
    write_episode(tmp_path / "raw" / "Home" / "pick" / "001", frames=3)
    export_lerobot(tmp_path / "raw", tmp_path / "out")
    info = json.loads((tmp_path / "out" / "meta" / "info.json").read_text())
    # LeRobot's defaults (lerobot/datasets/utils.py: DEFAULT_CHUNK_SIZE, DEFAULT_DATA_FILE_SIZE_IN_MB, ..._VIDEO_...)
    assert (info["chunks_size"], info["data_files_size_in_mb"], info["video_files_size_in_mb"]) == (1000, 100, 200)
    state = info["features"]["observation.state"]["info"]
    assert state["joints"] == {"shape": [2, 21, 3], "axes": ["hand", "joint", "xyz"], "unit": "m",
                               "frame": "WiLoR camera of the chest view", "values": [0, 126]}
    assert state["seen"]["values"] == [126, 128]
    tactile = info["features"]["observation.tactile"]["info"]
    assert tactile["grid"] == [2, 21, 21] and tactile["range"] == [0.0, 1.0]
    trackers = info["features"]["observation.trackers"]["info"]
    assert trackers["shape"] == [3, 7] and trackers["rotation"] == "quaternion w, x, y, z"
    assert np.array(info["features"]["observation.tactile"]["names"]).shape == (434,)
