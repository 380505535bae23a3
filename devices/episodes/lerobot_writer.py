"""Episodes written as a LeRobot v3.0 dataset (`touchanything export-lerobot`; the format in
`devices.episodes.lerobot_format`, the features in docs/data_formats.md).

Every episode goes whole into the current data file (parquet, one row per frame) and, per view, the current video
file (H.264, yuv420p, a key frame every 2 frames and no B-frames, so that frame i of the file is presented at
exactly i / fps and any frame decodes quickly); a file is closed and the next begun when it passes LeRobot's size
(100 MB data, 200 MB video). Columns carry the Hugging Face `datasets` feature types in the schema's metadata (a
hand's map is an Array3D (2, 21, 21), a flag pair a length-2 list), as `datasets.Dataset.to_parquet` writes them.
"""
from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from touchanything.core.snapshot import TRACKER_ROLES
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode import Episode, FrameSource
from touchanything.devices.episodes.lerobot_stats import aggregate, as_json, feature_stats, sample_indices, video_stats
from touchanything.devices.episodes.video_io import VideoWriter

VIDEO_CRF = 20
VIDEO_OPTIONS = {"g": "2", "bf": "0"}


def frame_features(episode: Episode, sensor_cells: np.ndarray) -> dict[str, np.ndarray]:
    """The non-video features of every frame of `episode` (`lerobot_format.FEATURE_INFO`): each (frames, values),
    hands in the order [left, right], no NaN. `sensor_cells`: (2, 21, 21) bool, the grid cells exported."""
    t = episode.num_frames
    joints = np.zeros((t, 2, 21, 3), np.float32) if episode.wilor is None else episode.wilor.joints.astype(np.float32)
    seen = np.zeros((t, 2), bool) if episode.wilor is None else episode.wilor.valid
    grids = np.full((t, 2, 21, 21), np.nan, np.float32) if episode.pressure is None else episode.pressure.grids
    cells = np.asarray(grids, np.float32)[:, sensor_cells]
    measured = np.isfinite(cells)
    hand_of_cell = np.argwhere(sensor_cells)[:, 0]
    poses = np.zeros((t, len(TRACKER_ROLES), 7), np.float32)
    trackers_valid = np.zeros((t, len(TRACKER_ROLES)), bool)
    if episode.trackers is not None:
        poses, trackers_valid = episode.trackers.poses.astype(np.float32), episode.trackers.valid
    return {fmt.STATE: np.concatenate([joints.reshape(t, -1), seen.astype(np.float32)], axis=1),
            fmt.TACTILE: np.where(measured, cells, 0.0).astype(np.float32),
            fmt.TACTILE_VALID: np.stack([measured[:, hand_of_cell == h].any(axis=1) for h in range(2)], axis=1).astype(np.float32),
            fmt.TRACKERS: poses.reshape(t, -1), fmt.TRACKERS_VALID: trackers_valid.astype(np.float32),
            fmt.CAPTURE_TIME: episode.timestamps_us.astype(np.int64)}


def numeric_features(sensor_cells: np.ndarray, views: tuple[str, ...]) -> dict[str, dict]:
    """info.json's entries of the non-video features (before any is renamed `action`); `views`: the exported ones,
    which `observation.views_valid` names."""
    features, dynamic = {}, {fmt.TACTILE: fmt.tactile_names(sensor_cells), fmt.VIEWS_VALID: list(views)}
    for name, dtype, size in ((fmt.STATE, "float32", len(fmt.STATE_NAMES)), (fmt.TACTILE, "float32", int(sensor_cells.sum())),
                              (fmt.TACTILE_VALID, "float32", 2), (fmt.TRACKERS, "float32", len(fmt.TRACKER_NAMES)),
                              (fmt.TRACKERS_VALID, "float32", len(TRACKER_ROLES)), (fmt.VIEWS_VALID, "float32", len(views)),
                              (fmt.CAPTURE_TIME, "int64", 1)):
        names = dynamic[name] if name in dynamic else fmt.FEATURE_NAMES[name]
        features[name] = {"dtype": dtype, "shape": [size], "names": names,
                          **({"info": fmt.FEATURE_INFO[name]} if name in fmt.FEATURE_INFO else {})}
    for name in fmt.INDEX_FEATURES:
        features[name] = {"dtype": "float32" if name == "timestamp" else "int64", "shape": [1], "names": None}
    return features


def _dtype(values: np.ndarray) -> str:
    return {"b": "bool", "i": "int64", "f": "float32"}[values.dtype.kind]


def _hf_feature(dtype: str, shape: tuple[int, ...]) -> dict:
    """A feature in the dictionary form of Hugging Face `datasets` 4 (`Features.to_dict()`), as LeRobot makes it."""
    if shape == (1,):
        return {"dtype": dtype, "_type": "Value"}
    if len(shape) == 1:
        return {"feature": {"dtype": dtype, "_type": "Value"}, "length": shape[0], "_type": "List"}
    return {"shape": list(shape), "dtype": dtype, "_type": f"Array{len(shape)}D"}


def _column(values: np.ndarray) -> pa.Array:
    """(frames, *shape) values as the arrow column of their `datasets` type: scalars, fixed-size lists (1-D) or
    nested lists (ArrayND)."""
    flat = pa.array(values.reshape(-1))
    if values.ndim == 1:
        return flat
    if values.ndim == 2:
        return pa.FixedSizeListArray.from_arrays(flat, values.shape[1])
    for size in reversed(values.shape[1:]):
        count = len(flat) // size
        flat = pa.ListArray.from_arrays(pa.array(np.arange(count + 1, dtype=np.int32) * size), flat)
    return flat


def _pictures(source: FrameSource, indices: Iterable[int]) -> Iterator[tuple[np.ndarray, bool]]:
    """Frames `indices` of `source` as the export writes them, each with whether it is the recorded picture: a frame
    the file no longer decodes is black (False), so that the times stay i / fps (and the statistics are those of the
    video written)."""
    blank = None
    for i in indices:
        image = source.read(i)
        if image is None:
            blank = np.zeros((source.height, source.width, 3), np.uint8) if blank is None else blank
        yield (blank, False) if image is None else (image, True)


@dataclass
class _OpenFile:
    """The data or video file being written: its chunk and file index, frames in it."""

    chunk: int = 0
    file: int = 0
    frames: int = 0

    def advance(self) -> None:
        self.file, self.frames = (0, 0) if self.file + 1 == fmt.CHUNKS_SIZE else (self.file + 1, 0)
        if self.file == 0:
            self.chunk += 1


@dataclass
class LeRobotWriter:
    """Write episodes with `add`, then `close()` for the metadata. `views`: the video features, each (width,
    height) in `sizes`; every episode must have them all, at that size, at `fps`. `splits`: info.json's split
    name → episode range "first:end"; `sensor_cells`: (2, 21, 21) bool, the grid cells exported; `action`: the
    feature written as LeRobot's `action` (one of `lerobot_format.ACTION_CHOICES`), None for none; `on_frame`:
    called after each frame of an episode written (every view's picture of it)."""

    folder: Path
    fps: int
    views: tuple[str, ...]
    sizes: dict[str, tuple[int, int]]
    splits: dict[str, str]
    sensor_cells: np.ndarray
    action: str | None = None
    on_frame: Callable[[], None] = lambda: None
    episodes: list[dict] = field(default_factory=list)
    tasks: dict[str, int] = field(default_factory=dict)
    _stats: list[dict[str, dict]] = field(default_factory=list)
    _frames: int = 0

    def __post_init__(self) -> None:
        self._data, self._data_writer = _OpenFile(), None
        self._videos = {view: _OpenFile() for view in self.views}
        self._video_writers: dict[str, VideoWriter] = {}

    def add(self, episode: Episode, task: str, extra: dict[str, str]) -> dict[str, int]:
        """Append one episode (its frames, videos, metadata and statistics); `extra`: more columns of its row in
        the episodes metadata (strings). Returns, per view that has any, how many of its frames the source did not
        decode (written black, 0.0 in `observation.views_valid`)."""
        index, frames = len(self.episodes), episode.num_frames
        row = {"episode_index": index, "tasks": [task], "length": frames, "data/chunk_index": self._data.chunk,
               "data/file_index": self._data.file, "dataset_from_index": self._frames, "dataset_to_index": self._frames + frames,
               **extra}
        placed, recorded = self._write_videos(episode, frames)
        features = {**frame_features(episode, self.sensor_cells), fmt.VIEWS_VALID: recorded}
        columns = {**self._index_columns(index, self.tasks.setdefault(task, len(self.tasks)), frames),
                   **{self._key(name): values for name, values in features.items()}}
        stats = {name: feature_stats(values) for name, values in columns.items()}
        self._write_data(columns)
        for view in self.views:
            sample = np.stack([image for image, _ in _pictures(episode.views[view], sample_indices(frames))])
            stats[fmt.VIEW_FEATURES[view]] = video_stats(sample)
        row.update(placed)
        row.update({f"stats/{key}/{stat}": np.asarray(value).tolist() for key, values in stats.items()
                    for stat, value in values.items()})
        self.episodes.append(row)
        self._stats.append(stats)
        self._frames += frames
        filled = frames - recorded.sum(axis=0).astype(int)
        return {view: int(count) for view, count in zip(self.views, filled) if count}

    def _key(self, name: str) -> str:
        """The key feature `name` is written under."""
        return fmt.ACTION if name == self.action else name

    def _index_columns(self, index: int, task_index: int, frames: int) -> dict[str, np.ndarray]:
        """LeRobot's own columns: time from the episode's start (exactly i / fps), indexes."""
        return {"timestamp": (np.arange(frames) / self.fps).astype(np.float32),
                "frame_index": np.arange(frames, dtype=np.int64), "episode_index": np.full(frames, index, np.int64),
                "index": np.arange(self._frames, self._frames + frames, dtype=np.int64),
                "task_index": np.full(frames, task_index, np.int64)}

    def _write_data(self, columns: dict[str, np.ndarray]) -> None:
        table = pa.table({name: _column(values) for name, values in columns.items()})
        hf = {name: _hf_feature(_dtype(values), values.shape[1:] or (1,)) for name, values in columns.items()}
        table = table.replace_schema_metadata({b"huggingface": json.dumps({"info": {"features": hf}}).encode()})
        if self._data_writer is None:
            path = self.folder / fmt.DATA_PATH.format(chunk_index=self._data.chunk, file_index=self._data.file)
            path.parent.mkdir(parents=True, exist_ok=True)
            self._data_writer = pq.ParquetWriter(path, table.schema, compression="snappy")
        self._data_writer.write_table(table)
        self._data.frames += table.num_rows
        if self._data_writer.file_handle is not None and self._data_writer.file_handle.tell() > fmt.DATA_FILE_MB * 1e6:
            self._data_writer.close()
            self._data_writer = None
            self._data.advance()

    def _write_videos(self, episode: Episode, frames: int) -> tuple[dict, np.ndarray]:
        """Append the episode's frames to each view's current video file, frame by frame (`on_frame` after each);
        the episodes-metadata columns, and (frames, views) float32: 1.0 where the picture is the recorded one."""
        writers = [self._video_writer(view) for view in self.views]
        recorded = np.zeros((frames, len(self.views)), np.float32)
        streams = [_pictures(episode.views[view], range(frames)) for view in self.views]
        for i, pictures in enumerate(zip(*streams)):
            for k, (image, is_recorded) in enumerate(pictures):
                writers[k].write(image)
                recorded[i, k] = is_recorded
            self.on_frame()
        placed = {}
        for view in self.views:
            placed.update(self._video_placed(view, frames))
        return placed, recorded

    def _video_writer(self, view: str) -> VideoWriter:
        """The open video file of `view` (a new one when none is open)."""
        if view not in self._video_writers:
            at = self._videos[view]
            path = self.folder / fmt.VIDEO_PATH.format(video_key=fmt.VIEW_FEATURES[view], chunk_index=at.chunk,
                                                        file_index=at.file)
            path.parent.mkdir(parents=True, exist_ok=True)
            self._video_writers[view] = VideoWriter(path, self.fps, VIDEO_CRF, fragmented=False, codec_options=VIDEO_OPTIONS)
        return self._video_writers[view]

    def _video_placed(self, view: str, frames: int) -> dict:
        """Where the episode's `frames` just written lie in `view`'s video file (the episodes-metadata columns); a
        file past LeRobot's size is closed and the next begun."""
        at, writer, key = self._videos[view], self._video_writers[view], fmt.VIEW_FEATURES[view]
        columns = {f"videos/{key}/chunk_index": at.chunk, f"videos/{key}/file_index": at.file,
                   f"videos/{key}/from_timestamp": at.frames / self.fps,
                   f"videos/{key}/to_timestamp": (at.frames + frames) / self.fps}
        at.frames += frames
        if writer.path.exists() and writer.path.stat().st_size > fmt.VIDEO_FILE_MB * 1e6:
            writer.close()
            del self._video_writers[view]
            at.advance()
        return columns

    def close(self) -> None:
        """Close the open files and write the metadata: info, stats, tasks, episodes."""
        if self._data_writer is not None:
            self._data_writer.close()
        for writer in self._video_writers.values():
            writer.close()
        meta = self.folder / "meta"
        meta.mkdir(parents=True, exist_ok=True)
        episodes = pa.Table.from_pylist(self.episodes)
        path = self.folder / fmt.EPISODES_PATH.format(chunk_index=0, file_index=0)
        path.parent.mkdir(parents=True, exist_ok=True)
        episodes = episodes.append_column("meta/episodes/chunk_index", pa.array([0] * len(self.episodes), pa.int64()))
        pq.write_table(episodes.append_column("meta/episodes/file_index", pa.array([0] * len(self.episodes), pa.int64())), path)
        tasks = pa.table({"task_index": pa.array(list(self.tasks.values()), pa.int64()), "task": list(self.tasks)})
        pq.write_table(tasks.replace_schema_metadata({b"pandas": json.dumps(_pandas_index("task", tasks)).encode()}),
                       self.folder / fmt.TASKS_PATH)
        stats = {key: aggregate([s[key] for s in self._stats]) for key in self._stats[0]} if self._stats else {}
        (self.folder / fmt.STATS_PATH).write_text(json.dumps(as_json(stats), indent=1))
        (self.folder / fmt.INFO_PATH).write_text(json.dumps(self.info(), indent=1))

    def info(self) -> dict:
        """`meta/info.json`."""
        features = {}
        for view in self.views:
            width, height = self.sizes[view]
            features[fmt.VIEW_FEATURES[view]] = {
                "dtype": "video", "shape": [height, width, 3], "names": ["height", "width", "channels"],
                "info": {"video.height": height, "video.width": width, "video.codec": "h264", "video.pix_fmt": "yuv420p",
                         "video.is_depth_map": False, "video.fps": self.fps, "video.channels": 3, "has_audio": False}}
        for name, feature in numeric_features(self.sensor_cells, self.views).items():
            if name == self.action:
                feature = {**feature, "info": {**feature.get("info", {}), "exported_from": name}}
            features[self._key(name)] = feature
        return {"codebase_version": fmt.CODEBASE_VERSION, "robot_type": fmt.ROBOT_TYPE,
                "total_episodes": len(self.episodes), "total_frames": self._frames, "total_tasks": len(self.tasks),
                "chunks_size": fmt.CHUNKS_SIZE,
                "data_files_size_in_mb": fmt.DATA_FILE_MB, "video_files_size_in_mb": fmt.VIDEO_FILE_MB, "fps": self.fps,
                "splits": self.splits, "data_path": fmt.DATA_PATH, "video_path": fmt.VIDEO_PATH,
                "features": features}


def _pandas_index(name: str, table: pa.Table) -> dict:
    """The `pandas` schema metadata that makes column `name` the frame's index when pandas reads the file (LeRobot
    reads `tasks.parquet` with pandas and takes a task's text from the index)."""
    columns = [{"name": c, "field_name": c, "pandas_type": "unicode" if c == name else "int64",
                "numpy_type": "object" if c == name else "int64", "metadata": None} for c in table.column_names]
    return {"index_columns": [name], "column_indexes": [], "columns": columns, "creator": {"library": "pyarrow"},
            "pandas_version": "2.2.0"}
