"""A LeRobot dataset laid out like the community EgoTouch conversion (codebase v2.0: one parquet and one MP4 per
episode, `meta/episodes.jsonl` and `meta/tasks.jsonl`, the head camera as `observation.images.main`, the
tactile maps (2, 21, 21) in the hand order [right, left] without it being stated, NaN outside the glove)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from touchanything.devices.episodes.video_io import VideoWriter

FPS = 30


def write_community_dataset(root: Path, grids: list[np.ndarray], images: list[np.ndarray]) -> Path:
    """Episodes k = 0… with `grids[k]` (T, 2, 21, 21) in [left, right] order (written as [right, left]) and
    `images[k]` (T, H, W, 3) uint8 as the head camera."""
    height, width = images[0].shape[1:3]
    info = {"codebase_version": "v2.0", "robot_type": "human", "total_episodes": len(grids),
            "total_frames": sum(len(g) for g in grids), "total_tasks": 1, "chunks_size": 1000, "fps": FPS,
            "splits": {"train": f"0:{len(grids)}"},
            "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
            "video_path": "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4",
            "features": {
                "observation.images.main": {"dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channel"]},
                "observation.pressure": {"dtype": "float32", "shape": [2, 21, 21], "names": None},
                "timestamp": {"dtype": "float32", "shape": [1], "names": None},
                "frame_index": {"dtype": "int64", "shape": [1], "names": None},
                "episode_index": {"dtype": "int64", "shape": [1], "names": None},
                "index": {"dtype": "int64", "shape": [1], "names": None},
                "task_index": {"dtype": "int64", "shape": [1], "names": None}}}
    (root / "meta").mkdir(parents=True)
    (root / "meta" / "info.json").write_text(json.dumps(info))
    (root / "meta" / "tasks.jsonl").write_text(json.dumps({"task_index": 0, "task": "touch things"}) + "\n")
    lines, start = [], 0
    for k, (grid, frames) in enumerate(zip(grids, images)):
        t = len(grid)
        lines.append(json.dumps({"episode_index": k, "tasks": ["touch things"], "length": t}))
        swapped = grid[:, ::-1].reshape(t, -1)
        table = pa.table({
            "observation.pressure": pa.FixedSizeListArray.from_arrays(pa.array(swapped.reshape(-1)), 2 * 21 * 21),
            "timestamp": pa.array(np.arange(t, dtype=np.float32) / FPS), "frame_index": pa.array(np.arange(t)),
            "episode_index": pa.array(np.full(t, k)), "index": pa.array(np.arange(start, start + t)),
            "task_index": pa.array(np.zeros(t, np.int64))})
        path = root / "data" / "chunk-000" / f"episode_{k:06d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, path)
        video = root / "videos" / "chunk-000" / "observation.images.main" / f"episode_{k:06d}.mp4"
        video.parent.mkdir(parents=True, exist_ok=True)
        with VideoWriter(video, FPS, crf=10, fragmented=False) as writer:
            for image in frames:
                writer.write(image)
        start += t
    (root / "meta" / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    return root
