"""Write raw EgoTouch episode folders frame by frame (videos, JSONL streams) and their pressure grids.

JSONL rows are flushed as they are written and videos are fragmented MP4, so a writer that dies keeps
everything up to its last second; `pressure_grids.npz` is computed from the glove stream at `close()`
(or later with `write_grids_from_glove`, which `touchanything grids FOLDER` runs).

Every stream keeps one entry per frame once it exists, so line numbers and video frames stay the frame
index: a JSONL stream that first appears at frame k starts with k empty lines and gets an empty line for
a frame without it; a video that first appears at frame k starts with k black frames and repeats its last
picture for a frame without it (as a rig that keeps the latest frame of every camera would).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from touchanything.devices.episodes.episode_files import write_pressure_grids
from touchanything.devices.episodes.episode_streams import glove_row, hands_row, read_glove, trackers_row
from touchanything.devices.episodes.jsonl import json_line
from touchanything.devices.episodes.raw_episode import GLOVE_FILE, GRIDS_FILE, ROKOKO_FILE, VIDEO_FILES, VIVE_FILE, WILOR_FILE
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.errors import DataError
from touchanything.devices.snapshot import FRAME_PERIOD_US
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.devices.tactile_pipeline import PressureGrids, TactileConfig, process_raw


@dataclass
class EpisodeFrame:
    """One frame to write. Arrays: images {view: (H, W, 3) uint8 RGB}; hands (2, 21, 3) + (2,) valid;
    glove_raw (2, 256) uint8 + (2,) present + (2, 4) quaternions w,x,y,z; trackers (3, 7) + (3,) valid."""

    images: dict[str, np.ndarray] = field(default_factory=dict)
    wilor: tuple[np.ndarray, np.ndarray] | None = None
    rokoko: tuple[np.ndarray, np.ndarray] | None = None
    glove: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    trackers: tuple[np.ndarray, np.ndarray] | None = None
    timestamp_us: int | None = None


def write_grids_from_glove(folder: Path, layout: TactileLayout | None = None,
                           config: TactileConfig = TactileConfig()) -> PressureGrids:
    """Compute `pressure_grids.npz` of an episode folder from its `jq_pressure.json`."""
    stream, _ = read_glove(Path(folder) / GLOVE_FILE)
    return _write_grids(Path(folder), stream.raw, layout or TactileLayout.default(), config)


def _write_grids(folder: Path, raw: np.ndarray, layout: TactileLayout, config: TactileConfig) -> PressureGrids:
    grids = process_raw(raw, layout, config)
    partial = folder / (GRIDS_FILE + ".partial.npz")
    write_pressure_grids(partial, grids.grids, grids.baseline_applied, grids.tactile_max, grids.bend_max)
    os.replace(partial, folder / GRIDS_FILE)
    return grids


class RawEpisodeWriter:
    """Writes one episode folder; streams appear when first given (earlier lines are left empty).
    crf / preset: the H.264 quality and x264 speed preset of the videos."""

    def __init__(self, folder: Path, layout: TactileLayout | None = None, config: TactileConfig = TactileConfig(),
                 crf: int = 20, preset: str = "veryfast") -> None:
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DataError(self.folder, None, f"cannot create the episode folder ({exc.strerror})") from None
        self.layout = layout or TactileLayout.default()
        self.config, self.crf, self.preset = config, crf, preset
        self.frames = 0
        self._videos: dict[str, VideoWriter] = {}
        self._last_images: dict[str, np.ndarray] = {}
        self._streams: dict[str, IO[str]] = {}
        self._glove_raw: list[np.ndarray] = []

    def _line(self, name: str, row: dict | None) -> None:
        """Append `row` (None: an empty line) to a JSONL stream; an OSError names the file."""
        try:
            handle = self._streams.get(name)
            if handle is None:
                if row is None:
                    return
                handle = self._streams[name] = open(self.folder / name, "w", buffering=1)
                handle.writelines("{}\n" for _ in range(self.frames))
            handle.write("{}\n" if row is None else json_line(row))
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(self.folder / name)) from exc

    def _video(self, view: str, image: np.ndarray) -> VideoWriter:
        """The view's writer, opened (after one black frame per earlier episode frame) when first seen."""
        video = self._videos.get(view)
        if video is None:
            video = self._videos[view] = VideoWriter(self.folder / VIDEO_FILES[view], crf=self.crf,
                                                                 preset=self.preset)
            black = np.zeros_like(image, dtype=np.uint8)
            for _ in range(self.frames):
                video.write(black)
        return video

    def write(self, frame: EpisodeFrame) -> None:
        """Append one frame to every stream (what the frame lacks is left empty or repeated, see above)."""
        index = self.frames
        for view, image in frame.images.items():
            self._video(view, image)
            self._last_images[view] = image
        for view, video in self._videos.items():
            video.write(self._last_images[view])
        stamp = frame.timestamp_us if frame.timestamp_us is not None else index * FRAME_PERIOD_US
        rows = {
            WILOR_FILE: None if frame.wilor is None else hands_row(index, *frame.wilor),
            ROKOKO_FILE: None if frame.rokoko is None else hands_row(index, *frame.rokoko),
            VIVE_FILE: None if frame.trackers is None else trackers_row(index, *frame.trackers),
            GLOVE_FILE: None if frame.glove is None else glove_row(index, stamp, *frame.glove),
        }
        for name, row in rows.items():
            self._line(name, row)
        if frame.glove is not None:
            raw, present, _ = frame.glove
            self._glove_raw.append(np.where(np.asarray(present)[:, None], raw, 0).astype(np.uint8))
        elif self._glove_raw:
            self._glove_raw.append(np.zeros((2, 256), np.uint8))
        self.frames += 1

    def close(self) -> PressureGrids | None:
        """Finish every video and stream (all of them, even when one fails: the first failure is raised
        after the rest are closed and the grids written); writes `pressure_grids.npz` when there is glove data."""
        failure: Exception | None = None
        for finish in [video.close for video in self._videos.values()] + [h.close for h in self._streams.values()]:
            try:
                finish()
            except Exception as exc:  # noqa: BLE001 - re-raised below, once everything else is closed
                failure = failure or exc
        self._videos, self._streams, self._last_images = {}, {}, {}
        grids = self._close_grids()
        if failure is not None:
            raise failure
        return grids

    def _close_grids(self) -> PressureGrids | None:
        if not self._glove_raw:
            return None
        raw = np.zeros((self.frames, 2, 256), np.uint8)
        raw[self.frames - len(self._glove_raw):] = np.stack(self._glove_raw)
        return _write_grids(self.folder, raw, self.layout, self.config)

    def __enter__(self) -> RawEpisodeWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
