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

import numpy as np

from touchanything.core.hand_pose import JOINT_NAMES, JOINTS_PER_HAND
from touchanything.core.snapshot import HANDS, TRACKER_ROLES, VIEW_NAMES
from touchanything.core.tactile_layout import GRID_SIZE

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
STATE = "observation.state"
TACTILE, TACTILE_VALID = "observation.tactile", "observation.tactile_valid"
TRACKERS, TRACKERS_VALID = "observation.trackers", "observation.trackers_valid"
VIEWS_VALID = "observation.views_valid"
"""Per exported view, named by it: 1.0 when the frame's picture is the recorded one, 0.0 when the source did not
decode it and a black picture stands in its place (named apart from the `observation.images` prefix, which is
the video features')."""
CAPTURE_TIME = "capture_time_us"
"""Not an `observation.*` feature: LeRobot's policies take every one of those as an input."""
ACTION = "action"
ACTION_CHOICES = (TACTILE, STATE, TRACKERS)
"""The features `export-lerobot --action` can write as LeRobot's `action` (moved, not copied: a policy takes every
other `observation.*` feature as input, so the target must not also be one)."""
INDEX_FEATURES = ("timestamp", "frame_index", "episode_index", "index", "task_index")
JOINTS, JOINTS_VALID = "observation.hand_joints", "observation.hand_joints_valid"
OLD_CAPTURE_TIME = "observation.capture_time_us"
"""Exports before 2026-11-27 held the joints (2, 21, 3) and their flags, and the capture times, here, and the maps
(2, 21, 21) with NaN outside the glove; the reader still takes them."""

POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")
JOINT_VALUES = len(HANDS) * JOINTS_PER_HAND * 3
STATE_NAMES = [f"{hand}.{joint}.{axis}" for hand in HANDS for joint in JOINT_NAMES for axis in "xyz"] + \
    [f"{hand}.seen" for hand in HANDS]
"""`observation.state`, 128 values: both hands' 21 joints (x, y, z in metres, WiLoR's camera of the chest view;
0 for a hand not seen), then whether each hand was seen (1.0 or 0.0)."""
TRACKER_NAMES = [f"{role}.{value}" for role in TRACKER_ROLES for value in POSE]
CELL_NAME = re.compile(r"(left|right)\.r(\d{2})c(\d{2})")


def tactile_names(sensor_cells: np.ndarray) -> list[str]:
    """The names of `observation.tactile`'s values: each hand's sensor cells ((2, 21, 21) bool), row by row,
    "left.r02c05" … (the grid cells the official data holds values in; the others are no sensor)."""
    return [f"{hand}.r{row:02d}c{col:02d}" for h, hand in enumerate(HANDS) for row, col in np.argwhere(sensor_cells[h])]


def cells_of(names: object) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(hand, row, column) index arrays of tactile value names, None unless `names` is a list of cell names."""
    if not isinstance(names, list) or not names:
        return None
    cells = []
    for name in names:
        match = CELL_NAME.fullmatch(name) if isinstance(name, str) else None
        if match is None or int(match[2]) >= GRID_SIZE or int(match[3]) >= GRID_SIZE:
            return None
        cells.append((HANDS.index(match[1]), int(match[2]), int(match[3])))
    hand, row, column = np.array(cells).T
    return hand, row, column


FEATURE_NAMES = {TACTILE_VALID: list(HANDS), TRACKERS: TRACKER_NAMES, TRACKERS_VALID: list(TRACKER_ROLES),
                 STATE: STATE_NAMES, CAPTURE_TIME: None}
"""The `names` of each exported feature (the tactile names depend on the glove layout: `tactile_names`). Every
feature is 1-D and named value by value, so Rerun's LeRobot importer plots each as labelled series and LeRobot's
statistics are per value; a name map of two entries makes Rerun reject the whole dataset. The flags are float32
0.0 / 1.0: LeRobot's normaliser cannot subtract a mean from a bool tensor, and Rerun does not load bool features."""
FEATURE_INFO = {
    STATE: {"joints": {"shape": [len(HANDS), JOINTS_PER_HAND, 3], "axes": ["hand", "joint", "xyz"], "unit": "m",
                       "frame": "WiLoR camera of the chest view", "values": [0, JOINT_VALUES]},
            "seen": {"values": [JOINT_VALUES, JOINT_VALUES + len(HANDS)], "meaning": "1.0 when the hand was seen"}},
    TACTILE: {"grid": [len(HANDS), GRID_SIZE, GRID_SIZE], "range": [0.0, 1.0],
              "cells": "value k is the grid cell its name gives (hand.rROWcCOLUMN); cells without a sensor are not "
                       "stored; a hand not measured in a frame (observation.tactile_valid false) holds 0"},
    TRACKERS: {"shape": [len(TRACKER_ROLES), len(POSE)], "unit": "m", "frame": "SteamVR tracking space",
               "rotation": "quaternion w, x, y, z"},
    VIEWS_VALID: {"views": "value k is the video feature observation.images.<name k>",
                  "meaning": "1.0 when the picture is the recorded one; 0.0 when the source did not decode that frame "
                             "and a black picture stands in its place"},
}
"""The `info` of the non-video features: how their values form the project's arrays (LeRobot ignores it)."""

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
