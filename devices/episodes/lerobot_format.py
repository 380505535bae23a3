"""The LeRobot dataset format (codebase v3.0, as `lerobot` 0.4 writes and reads it) and the features this project
exports, shared by the writer and the reader.

A dataset root holds `meta/info.json` (version, fps, features, path templates), `meta/stats.json`,
`meta/tasks.parquet` (index `task`: the task text; column `task_index`), `meta/episodes/chunk-XXX/file-XXX.parquet`
(one row per episode: its frames `dataset_from_index`–`dataset_to_index` in the data files, where each video
feature's frames lie, per-episode stats), `data/chunk-XXX/file-XXX.parquet` (one row per frame, several episodes
per file) and `videos/<feature>/chunk-XXX/file-XXX.mp4` (several episodes per file, one after the other; an
episode's frame i is at `from_timestamp + i / fps`). The older layout (v2.x, as the community EgoTouch conversion
uses) has one parquet and one MP4 per episode and `meta/episodes.jsonl`; the reader takes both.

An episode of a dataset is addressed as `ROOT/episode_NNNNNN` (its index, six digits), a path that does not
exist on disk: `open_episode` resolves it.
"""
from __future__ import annotations

import re
from pathlib import Path

from touchanything.devices.snapshot import HANDS, TRACKER_ROLES, VIEW_NAMES

CODEBASE_VERSION = "v3.0"
INFO_PATH, STATS_PATH, TASKS_PATH = Path("meta/info.json"), Path("meta/stats.json"), Path("meta/tasks.parquet")
EPISODES_DIR, DATA_DIR = Path("meta/episodes"), Path("data")
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
DATA_PATH = f"data/{CHUNK_FILE}.parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"
EPISODES_PATH = f"meta/episodes/{CHUNK_FILE}.parquet"
CHUNKS_SIZE, DATA_FILE_MB, VIDEO_FILE_MB = 1000, 100, 200
"""Files per chunk folder, and the size at which a data / video file is closed and the next begun (LeRobot's)."""
ROBOT_TYPE = "egotouch_human"
"""`robot_type` of the export: two human hands with tactile gloves, no robot."""

VIEW_FEATURES = {view: f"observation.images.{view}" for view in VIEW_NAMES}
JOINTS, JOINTS_VALID = "observation.hand_joints", "observation.hand_joints_valid"
TACTILE = "observation.tactile"
TRACKERS, TRACKERS_VALID = "observation.trackers", "observation.trackers_valid"
CAPTURE_TIME = "observation.capture_time_us"
INDEX_FEATURES = ("timestamp", "frame_index", "episode_index", "index", "task_index")

FEATURE_NAMES = {
    JOINTS: {"hand": list(HANDS)},
    JOINTS_VALID: list(HANDS),
    TACTILE: {"hand": list(HANDS)},
    TRACKERS: {"tracker": list(TRACKER_ROLES)},
    TRACKERS_VALID: list(TRACKER_ROLES),
    CAPTURE_TIME: None,
}
"""The `names` of each exported feature: the hand order is stated in every hand feature (official: left, right).
Each is None, a flat list or a map with exactly one entry — the forms Rerun's LeRobot importer accepts (a map of
two entries makes it reject the whole dataset); what each axis holds goes into the feature's `info`."""
FEATURE_INFO = {
    JOINTS: {"axes": ["hand", "joint", "xyz"]},
    TACTILE: {"axes": ["hand", "row", "column"]},
    TRACKERS: {"axes": ["tracker", "pose"], "pose": ["x", "y", "z", "qw", "qx", "qy", "qz"]},
}
"""The `info` of the multi-dimensional features: their axes (LeRobot and Rerun ignore it; video features carry
their own `info` the same way)."""

VIEW_ALIASES = {"ego": "ego", "main": "ego", "chest": "ego", "head": "ego", "wrist_left": "wrist_left",
                "left_wrist": "wrist_left", "wrist_right": "wrist_right", "right_wrist": "wrist_right"}
"""Video feature names (the last part of `observation.images.<name>`) read as the project's views; `main` is the
community EgoTouch conversion's head camera."""
EPISODE_ADDRESS = re.compile(r"episode_(\d{6})")


def episode_address(root: Path, index: int) -> Path:
    """The path that names episode `index` of the dataset at `root`."""
    return Path(root) / f"episode_{index:06d}"


def is_lerobot_root(path: Path) -> bool:
    """A folder holding `meta/info.json`."""
    return (Path(path) / INFO_PATH).is_file()


def parse_address(path: Path) -> tuple[Path, int] | None:
    """(dataset root, episode index) when `path` is `ROOT/episode_NNNNNN` of a LeRobot dataset, else None."""
    path = Path(path)
    match = EPISODE_ADDRESS.fullmatch(path.name)
    if match is None or not is_lerobot_root(path.parent):
        return None
    return path.parent, int(match.group(1))
