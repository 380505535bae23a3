"""The LeRobot writer (`devices/episodes/lerobot_writer.py`) at its edges: an episode
without pose, pressure or trackers, hands not measured written as 0 and flagged, the chunk and file numbering, and
an export whose data and video files are closed after every episode (LeRobot's 100 / 200 MB limits made tiny),
read back frame by frame."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from conftest import frame_image, write_episode
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.lerobot_export import export_lerobot
from touchanything.devices.episodes.lerobot_writer import LeRobotWriter, _OpenFile, frame_features
from touchanything.devices.episodes.video_io import VideoReader

SENSOR_CELLS = TactileLayout.default().valid


def _closest(picture: np.ndarray, pictures: list[np.ndarray]) -> int:
    """The index of the picture in `pictures` nearest to `picture` (mean absolute difference): which source frame a
    decoded frame shows, whatever the codec's error."""
    return int(np.argmin([np.abs(picture.astype(int) - p.astype(int)).mean() for p in pictures]))


def _video_only_episode(folder: Path, frames: int, first_picture: int = 0) -> Path:
    """A raw episode with the three cameras and nothing else (no pose, glove or trackers); its frame i shows
    `frame_image`'s picture `first_picture + i`."""
    with RawEpisodeWriter(folder, crf=10) as writer:
        for i in range(frames):
            writer.write(EpisodeFrame(images={v: frame_image(k, first_picture + i, (48, 64)) for k, v in enumerate(VIEW_NAMES)}))
    return folder


def test_an_episode_without_pose_pressure_or_trackers_is_zeros_flagged_unseen(tmp_path):
    with open_episode(_video_only_episode(tmp_path / "Home" / "idle" / "001", 5)) as episode:
        assert episode.wilor is None and episode.pressure is None and episode.trackers is None
        features = frame_features(episode, SENSOR_CELLS)
    cells = int(SENSOR_CELLS.sum())
    # the widths info.json names: 2 × 21 joints × xyz + 2 seen flags, one value per sensor cell, 3 trackers × 7
    assert features[fmt.STATE].shape == (5, 2 * 21 * 3 + 2) and not features[fmt.STATE].any()
    assert features[fmt.TACTILE].shape == (5, cells) and not features[fmt.TACTILE].any()
    assert features[fmt.TACTILE_VALID].shape == (5, 2) and not features[fmt.TACTILE_VALID].any()
    assert features[fmt.TRACKERS].shape == (5, 21) and not features[fmt.TRACKERS].any()
    assert features[fmt.TRACKERS_VALID].shape == (5, 3) and not features[fmt.TRACKERS_VALID].any()
    assert features[fmt.STATE].dtype == np.float32 and features[fmt.CAPTURE_TIME].dtype == np.int64


def test_a_hand_not_measured_is_written_as_zero_and_flagged(tmp_path):
    folder = write_episode(tmp_path / "Home" / "press" / "001", frames=6, seed=2)
    with np.load(folder / "pressure_grids.npz") as grids:
        arrays = dict(grids)
    arrays["right_pressure_grid"][1::2] = np.nan  # the right glove not measured on odd frames
    np.savez(folder / "pressure_grids.npz", **arrays)
    with open_episode(folder) as episode:
        features = frame_features(episode, SENSOR_CELLS)
        left_cells = int(SENSOR_CELLS[0].sum())
        right = features[fmt.TACTILE][:, left_cells:]
        assert features[fmt.TACTILE_VALID].tolist() == [[1.0, float(i % 2 == 0)] for i in range(6)]
        assert (right[1::2] == 0.0).all() and np.array_equal(right[0::2], episode.pressure.grids[0::2, 1][:, SENSOR_CELLS[1]])
        np.testing.assert_array_equal(features[fmt.TACTILE][:, :left_cells], episode.pressure.grids[:, 0][:, SENSOR_CELLS[0]])


def test_files_are_numbered_within_a_chunk_and_the_thousandth_begins_the_next_chunk():
    at = _OpenFile(chunk=0, file=998, frames=40)
    at.advance()
    assert (at.chunk, at.file, at.frames) == (0, 999, 0)
    at.frames = 12
    at.advance()  # LeRobot's chunks hold 1000 files: file-000 … file-999
    assert (at.chunk, at.file, at.frames) == (1, 0, 0)
    at.advance()
    assert (at.chunk, at.file, at.frames) == (1, 1, 0)


def test_files_closed_after_every_episode_read_back_frame_by_frame(tmp_path, monkeypatch):
    """With LeRobot's file sizes made tiny, each episode begins new data and video files (file-001, -002): the
    episodes metadata points into them, each episode's video starts at 0 s of its file, and reading back gives the
    source's streams and pictures."""
    root = tmp_path / "raw"
    sources = [write_episode(root / "Home" / "pick" / f"00{k}", frames=frames, seed=k) for k, frames in ((1, 7), (2, 5), (3, 6))]
    monkeypatch.setattr(fmt, "DATA_FILE_MB", 1e-6)
    monkeypatch.setattr(fmt, "VIDEO_FILE_MB", 1e-6)
    out = tmp_path / "lerobot"
    export_lerobot(root, out)
    for k in range(3):
        assert (out / "data" / "chunk-000" / f"file-{k:03d}.parquet").is_file()
        assert (out / "videos" / fmt.VIEW_FEATURES["ego"] / "chunk-000" / f"file-{k:03d}.mp4").is_file()
    rows = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [row["data/file_index"] for row in rows] == [0, 1, 2]
    assert [row["dataset_from_index"] for row in rows] == [0, 7, 12] and [row["dataset_to_index"] for row in rows] == [7, 12, 18]
    key = fmt.VIEW_FEATURES["wrist_right"]
    assert [row[f"videos/{key}/file_index"] for row in rows] == [0, 1, 2]
    assert [row[f"videos/{key}/from_timestamp"] for row in rows] == [0.0, 0.0, 0.0]
    assert [row[f"videos/{key}/to_timestamp"] for row in rows] == pytest.approx([7 / 30, 5 / 30, 6 / 30])
    # the episodes metadata is one file: every row says it lies in chunk 0, file 0
    assert {(row["meta/episodes/chunk_index"], row["meta/episodes/file_index"]) for row in rows} == {(0, 0)}
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["total_frames"] == 18 and info["total_episodes"] == 3
    for index, source in enumerate(sources):
        with open_episode(source) as raw, open_episode(out / f"episode_{index:06d}") as back:
            assert back.num_frames == raw.num_frames and back.problems == []
            np.testing.assert_array_equal(back.wilor.joints, raw.wilor.joints)
            np.testing.assert_array_equal(back.pressure.grids, raw.pressure.grids)
            for view in VIEW_NAMES:
                pictures = [raw.views[view].read(i) for i in range(raw.num_frames)]
                assert [_closest(back.views[view].read(i), pictures) for i in range(raw.num_frames)] == list(range(raw.num_frames))
                assert back.views[view].read(raw.num_frames) is None


def test_episodes_after_the_first_read_their_own_pictures_from_a_shared_video_file(tmp_path):
    """In one video file the second episode's frames follow the first's (from_timestamp = 7 / 30 s): its frame i is
    its source's frame i (pictures 20…), not the file's frame i (the first episode's)."""
    root = tmp_path / "raw"
    first = write_episode(root / "Home" / "pick" / "001", frames=7, seed=1)
    second = _video_only_episode(root / "Office" / "press" / "002", 5, first_picture=20)
    out = tmp_path / "lerobot"
    export_lerobot(root, out)
    rows = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert rows[1][f"videos/{fmt.VIEW_FEATURES['ego']}/from_timestamp"] == pytest.approx(7 / 30)
    with open_episode(first) as one, open_episode(second) as two, open_episode(out / "episode_000001") as back:
        pictures = [one.views["ego"].read(i) for i in range(7)] + [two.views["ego"].read(i) for i in range(5)]
        assert [_closest(back.views["ego"].read(i), pictures) for i in range(5)] == [7, 8, 9, 10, 11]


class _FirstFrames:
    """A FrameSource that gives only the first `count` frames of `source` (a file that no longer decodes the rest)."""

    def __init__(self, source, count: int) -> None:
        self.source, self.count = source, count
        self.width, self.height, self.num_frames = source.width, source.height, source.num_frames

    def read(self, index: int) -> np.ndarray | None:
        return self.source.read(index) if index < self.count else None

    def close(self) -> None:
        self.source.close()


def test_frames_a_video_no_longer_decodes_are_written_black_and_the_file_is_a_plain_mp4(tmp_path):
    """The left wrist video decodes 3 of the episode's 6 frames: the export writes frames 3…5 black, so that frame i
    stays at i / fps, says so (3 filled) and marks them 0.0 in observation.views_valid, which the reader reads as
    missing frames; LeRobot's video files are plain MP4 (one index, no fragments: its decoders seek by it); the
    video features' info is what LeRobot writes for 3-channel H.264 without sound; tasks.parquet carries the pandas
    index LeRobot reads task texts from."""
    folder = write_episode(tmp_path / "raw" / "Home" / "pick_up_bottle" / "001", frames=6, seed=3)
    out = tmp_path / "lerobot"
    with open_episode(folder) as episode:
        sizes = {view: (source.width, source.height) for view, source in episode.views.items()}
        pictures = [episode.views["wrist_left"].read(i) for i in range(3)]
        episode.views["wrist_left"] = _FirstFrames(episode.views["wrist_left"], 3)
        writer = LeRobotWriter(out, 30, VIEW_NAMES, sizes, {"train": "0:1"}, SENSOR_CELLS)
        assert writer.add(episode, "pick up bottle", {}) == {"wrist_left": 3}
        writer.close()
    with open_episode(out / "episode_000000") as back:
        assert back.num_frames == 6 and len(back.problems) == 1
        assert "observation.views_valid: wrist_left: 3 of 6 frames did not decode in the source" in back.problems[0]
        assert [_closest(back.views["wrist_left"].read(i), pictures) for i in range(3)] == [0, 1, 2]
        assert [back.views["wrist_left"].read(i) for i in range(3, 6)] == [None] * 3
    path = out / "videos" / fmt.VIEW_FEATURES["wrist_left"] / "chunk-000" / "file-000.mp4"
    with VideoReader(path) as video:
        assert all(video.read(i).mean() < 2 for i in range(3, 6))  # black in the file (up to the codec)
    assert b"moov" in path.read_bytes() and b"moof" not in path.read_bytes()
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["features"][fmt.VIEW_FEATURES["ego"]]["info"] == {
        "video.height": 48, "video.width": 64, "video.codec": "h264", "video.pix_fmt": "yuv420p",
        "video.is_depth_map": False, "video.fps": 30, "video.channels": 3, "has_audio": False}
    assert {name: info["features"][name] for name in ("timestamp", "frame_index", "episode_index", "index", "task_index")} == {
        "timestamp": {"dtype": "float32", "shape": [1], "names": None},
        **{name: {"dtype": "int64", "shape": [1], "names": None} for name in ("frame_index", "episode_index", "index", "task_index")}}
    stats = json.loads((out / "meta" / "stats.json").read_text())
    assert stats["observation.state"]["count"] == [6]
    tasks = pq.read_table(out / "meta" / "tasks.parquet")
    pandas = json.loads(tasks.schema.metadata[b"pandas"])
    assert tasks["task"].to_pylist() == ["pick up bottle"] and pandas["index_columns"] == ["task"]
    assert {c["name"]: (c["pandas_type"], c["numpy_type"]) for c in pandas["columns"]} == {
        "task": ("unicode", "object"), "task_index": ("int64", "int64")}
