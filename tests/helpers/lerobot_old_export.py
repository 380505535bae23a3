"""An export as `export-lerobot` wrote it before 2026-11-27: the joints (2, 21, 3) and the maps (2, 21, 21) with NaN
outside the glove as multi-dimensional features, their hand order in `names` maps of two entries, the trackers
(3, 7), bool flags, `observation.capture_time_us`; made from a current export of the same raw episodes (its
videos and episodes metadata kept)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.lerobot_writer import _column

HANDS = ["left", "right"]
OLD_FEATURES = {
    "observation.hand_joints": {"dtype": "float32", "shape": [2, 21, 3], "names": {"axes": ["hand", "joint", "xyz"], "hand": HANDS}},
    "observation.hand_joints_valid": {"dtype": "bool", "shape": [2], "names": {"hand": HANDS}},
    "observation.tactile": {"dtype": "float32", "shape": [2, 21, 21], "names": {"axes": ["hand", "row", "column"], "hand": HANDS}},
    "observation.trackers": {"dtype": "float32", "shape": [3, 7], "names": {"axes": ["tracker", "pose"]}},
    "observation.trackers_valid": {"dtype": "bool", "shape": [3], "names": None},
}


def make_old_export(export: Path, raw_episodes: list[Path]) -> None:
    """Rewrite the current `export` of `raw_episodes` (in its episode order, one data file) in the old layout."""
    columns: dict[str, list[np.ndarray]] = {name: [] for name in OLD_FEATURES}
    for path in raw_episodes:
        with open_episode(path) as episode:
            columns["observation.hand_joints"].append(episode.wilor.joints.astype(np.float32))
            columns["observation.hand_joints_valid"].append(episode.wilor.valid)
            columns["observation.tactile"].append(episode.pressure.grids.astype(np.float32))
            columns["observation.trackers"].append(episode.trackers.poses.astype(np.float32))
            columns["observation.trackers_valid"].append(episode.trackers.valid)
    data_path = export / "data" / "chunk-000" / "file-000.parquet"
    table = pq.read_table(data_path)
    keep = ["timestamp", "frame_index", "episode_index", "index", "task_index"]
    table = pa.table({**{name: table[name] for name in keep}, "observation.capture_time_us": table["capture_time_us"],
                      **{name: _column(np.concatenate(values)) for name, values in columns.items()}})
    pq.write_table(table, data_path)
    info_path = export / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"] = {k: v for k, v in info["features"].items() if k in keep or k.startswith("observation.images")}
    info["features"].update(OLD_FEATURES, **{"observation.capture_time_us": {"dtype": "int64", "shape": [1], "names": None}})
    info_path.write_text(json.dumps(info))
