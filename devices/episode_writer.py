"""Write raw EgoTouch episode folders frame by frame (videos, JSONL streams) and their pressure grids.

JSONL rows are flushed as they are written and videos are fragmented MP4, so a writer that dies keeps
everything up to its last second; `pressure_grids.npz` is computed from the glove stream at `close()`
(or later with `write_grids_from_glove`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from devices.episode_files import write_pressure_grids
from devices.episode_streams import glove_row, hands_row, read_glove, trackers_row
from devices.errors import DataError
from devices.jsonl import json_line
from devices.raw_episode import GLOVE_FILE, GRIDS_FILE, ROKOKO_FILE, VIDEO_FILES, VIVE_FILE, WILOR_FILE
from devices.snapshot import FRAME_PERIOD_US
from devices.tactile_layout import TactileLayout
from devices.tactile_pipeline import PressureGrids, TactileConfig, process_raw
from devices.video_io import VideoWriter


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
    """Writes one episode folder; streams appear when first given (earlier lines are left empty)."""

    def __init__(self, folder: Path, layout: TactileLayout | None = None, config: TactileConfig = TactileConfig(),
                 crf: int = 20) -> None:
        self.folder = Path(folder)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DataError(self.folder, None, f"cannot create the episode folder ({exc.strerror})") from None
        self.layout = layout or TactileLayout.default()
        self.config, self.crf = config, crf
        self.frames = 0
        self._videos: dict[str, VideoWriter] = {}
        self._streams: dict[str, IO[str]] = {}
        self._glove_raw: list[np.ndarray] = []

    def _line(self, name: str, row: dict) -> None:
        handle = self._streams.get(name)
        if handle is None:
            handle = self._streams[name] = open(self.folder / name, "w", buffering=1)
            handle.writelines("{}\n" for _ in range(self.frames))
        handle.write(json_line(row))

    def write(self, frame: EpisodeFrame) -> None:
        """Append one frame to every stream it carries."""
        index = self.frames
        for view, image in frame.images.items():
            if view not in self._videos:
                self._videos[view] = VideoWriter(self.folder / VIDEO_FILES[view], crf=self.crf)
            self._videos[view].write(image)
        if frame.wilor is not None:
            self._line(WILOR_FILE, hands_row(index, *frame.wilor))
        if frame.rokoko is not None:
            self._line(ROKOKO_FILE, hands_row(index, *frame.rokoko))
        if frame.trackers is not None:
            self._line(VIVE_FILE, trackers_row(index, *frame.trackers))
        stamp = frame.timestamp_us if frame.timestamp_us is not None else index * FRAME_PERIOD_US
        if frame.glove is not None:
            self._line(GLOVE_FILE, glove_row(index, stamp, *frame.glove))
            raw, present, _ = frame.glove
            self._glove_raw.append(np.where(np.asarray(present)[:, None], raw, 0).astype(np.uint8))
        elif self._glove_raw:
            self._glove_raw.append(np.zeros((2, 256), np.uint8))
        self.frames += 1

    def close(self) -> PressureGrids | None:
        """Finish the videos and streams; writes `pressure_grids.npz` when there is glove data."""
        for video in self._videos.values():
            video.close()
        for handle in self._streams.values():
            handle.close()
        self._videos, self._streams = {}, {}
        if not self._glove_raw:
            return None
        raw = np.zeros((self.frames, 2, 256), np.uint8)
        raw[self.frames - len(self._glove_raw):] = np.stack(self._glove_raw)
        return _write_grids(self.folder, raw, self.layout, self.config)

    def __enter__(self) -> "RawEpisodeWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
