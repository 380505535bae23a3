"""Write raw EgoTouch episode folders frame by frame (videos, JSONL streams) and their pressure grids.

Every stream is written under its temporary name (`.chest.mp4.partial-<pid>`, marked as a recording's:
`temporary_files`) and renamed into place by `close()`, which never replaces a file: a folder that already holds
one of the episode's files is refused when the writer is made, so nothing is ever written through a link or over
a file of someone else's. JSONL rows are flushed as they are written and videos are fragmented MP4, so a writer
that dies keeps everything up to its last second under the temporary names, where the readers find it
(`temporary_files.recorded_stream`); `pressure_grids.npz` is computed from the glove stream at `close()`
(or later with `write_grids_from_glove`, which `touchanything grids FOLDER` runs). What the OS holds
reaches the disk when the writer's owner calls `sync()` (every file fsync'ed, and the folder's directory
when files were created since), and at `close()` when the writer is `durable`: that is what survives a
crash of the machine (the recorder calls `sync()` on a cadence).

Every stream keeps one entry per frame once it exists, so line numbers and video frames stay the frame
index: a JSONL stream that first appears at frame k starts with k empty lines and gets an empty line for
a frame without it; a video that first appears at frame k starts with k black frames and repeats its last
picture for a frame without it (as a rig that keeps the latest frame of every camera would).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import IO

import numpy as np

from touchanything.core.errors import DataError, UserError
from touchanything.core.output_safety import fsync_fd, fsync_path, rename_new, replacing
from touchanything.core.snapshot import FRAME_PERIOD_US
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.temporary_files import mark, recorded_stream, temporary_path, unmark
from touchanything.devices.episodes.episode_files import write_pressure_grids
from touchanything.devices.episodes.episode_streams import glove_row, hands_row, read_glove, trackers_row
from touchanything.devices.episodes.jsonl import json_line
from touchanything.devices.episodes.raw_episode import (
    GLOVE_FILE,
    GRIDS_FILE,
    ROKOKO_FILE,
    VIDEO_FILES,
    VIVE_FILE,
    WILOR_FILE,
    episode_file,
)
from touchanything.devices.episodes.video_io import VideoWriter
from touchanything.devices.tactile_pipeline import PressureGrids, TactileConfig, process_raw

EPISODE_FILES = (*VIDEO_FILES.values(), WILOR_FILE, ROKOKO_FILE, VIVE_FILE, GLOVE_FILE, GRIDS_FILE)
"""Every file `RawEpisodeWriter` may create."""


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


def check_new_episode(folder: Path) -> None:
    """UserError when `folder` holds a file (or link) of an episode's names, or a recording cut short: an episode
    is written into a folder without them (a user's `left.mp4` beside their notes is theirs)."""
    for name in EPISODE_FILES:
        if os.path.lexists(Path(folder) / name) or recorded_stream(folder, name) is not None:
            what = "exists" if os.path.lexists(Path(folder) / name) else "is in it as a recording cut short"
            raise UserError(f"{Path(folder) / name}: {what}; an episode is written into a folder without its files "
                            "(nothing is replaced): choose a new folder")


def write_grids_from_glove(folder: Path, layout: TactileLayout | None = None,
                           config: TactileConfig = TactileConfig()) -> PressureGrids:
    """Compute `pressure_grids.npz` of an episode folder from its `jq_pressure.json`, written under the output
    rule (`output_safety.replacing`: a temporary file synced and renamed into place, the folder synced after; a
    failed write, disk full included, leaves the old file and no temporary one).

    A stream without one usable hand sample (empty, or every sample malformed or non-finite) raises DataError
    before anything is written: the existing grids are kept rather than replaced by meaningless ones."""
    path = episode_file(folder, GLOVE_FILE)
    stream, problems = read_glove(path)
    if not stream.present.any():
        reason = "no frames" if len(stream.present) == 0 else f"none of its {len(stream.present)} frames holds a usable sample"
        detail = f" ({problems[0]})" if problems else ""
        raise DataError(path, None, f"cannot compute grids: {reason}{detail}; {GRIDS_FILE} left as it was")
    grids = process_raw(stream.raw, layout or TactileLayout.default(), config)
    with replacing(Path(folder) / GRIDS_FILE) as part:
        write_pressure_grids(part, grids.grids, grids.baseline_applied, grids.tactile_max, grids.bend_max)
    return grids


class RawEpisodeWriter:
    """Writes one episode folder; streams appear when first given (earlier lines are left empty).
    crf / preset: the H.264 quality and x264 speed preset of the videos. durable: `close()` fsyncs every
    file and the folder (see `sync()`)."""

    def __init__(self, folder: Path, layout: TactileLayout | None = None, config: TactileConfig = TactileConfig(),
                 crf: int = 20, preset: str = "veryfast", durable: bool = False) -> None:
        self.folder = Path(folder)
        check_new_episode(self.folder)
        created = [p for p in (self.folder, *self.folder.parents) if not p.exists()]
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DataError(self.folder, None, f"cannot create the episode folder ({exc.strerror})") from None
        self.layout = layout or TactileLayout.default()
        self.config, self.crf, self.preset, self.durable = config, crf, preset, durable
        self.frames = 0
        self._videos: dict[str, VideoWriter] = {}
        self._last_images: dict[str, np.ndarray] = {}
        self._streams: dict[str, IO[str]] = {}
        # directories whose entries changed since the last sync: the parents of the folders mkdir created
        # (outermost first), then the folder itself whenever a file is created in it
        self._new_entries: list[Path] = [p.parent for p in reversed(created)]

    def _line(self, name: str, row: dict | None) -> None:
        """Append `row` (None: an empty line) to a JSONL stream; an OSError names the file."""
        try:
            handle = self._streams.get(name)
            if handle is None:
                if row is None:
                    return
                handle = self._streams[name] = open(self._begin(name), "x", buffering=1)
                handle.writelines("{}\n" for _ in range(self.frames))
            handle.write("{}\n" if row is None else json_line(row))
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(self.folder / name)) from exc

    def _video(self, view: str, image: np.ndarray) -> VideoWriter:
        """The view's writer, opened (after one black frame per earlier episode frame) when first seen."""
        video = self._videos.get(view)
        if video is None:
            video = self._videos[view] = VideoWriter(self._begin(VIDEO_FILES[view]), crf=self.crf, preset=self.preset)
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
        self.frames += 1

    def _begin(self, name: str) -> Path:
        """The temporary path stream `name` is written under, its recording marker written first."""
        temporary = temporary_path(self.folder / name)
        mark(temporary, "recording", name=name)
        self._created()
        return temporary

    def _created(self) -> None:
        if self.folder not in self._new_entries:
            self._new_entries.append(self.folder)

    def sync(self) -> None:
        """fsync every file written so far (the videos' completed fragments, every JSONL line), then the
        directories whose entries changed since the last sync (new files, new folders), so that all of it
        survives a power loss. An OSError names the file."""
        unborn = [video for video in self._videos.values() if not video.sync()]
        for name, handle in self._streams.items():
            try:
                handle.flush()
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror, str(self.folder / name)) from exc
            fsync_fd(handle.fileno(), self.folder / name)
        self._sync_entries()
        if unborn:  # a video whose file FFmpeg has not created yet: its entry is synced by a later round
            self._created()

    def _sync_entries(self) -> None:
        while self._new_entries:
            fsync_path(self._new_entries[0], directory=True)
            self._new_entries.pop(0)

    def close(self) -> PressureGrids | None:
        """Finish every video and stream (all of them, even when one fails: the first failure is raised
        after the rest are closed and the grids written); writes `pressure_grids.npz` when there is glove data.
        A `durable` writer fsyncs each file as it closes it, the grids, and the directories."""
        failure: Exception | None = None
        finishers = [partial(video.close, sync=self.durable) for video in self._videos.values()]
        finishers += [partial(self._close_stream, name, handle) for name, handle in self._streams.items()]
        if self.durable:
            finishers.append(self._sync_entries)  # after the files: each is synced as it closes
        for finish in finishers:
            try:
                finish()
            except Exception as exc:  # noqa: BLE001 - re-raised below, once everything else is closed
                failure = failure or exc
        names = [VIDEO_FILES[view] for view in self._videos] + list(self._streams)
        has_glove = GLOVE_FILE in self._streams
        self._videos, self._streams, self._last_images = {}, {}, {}
        failure = self._put_in_place(names) or failure
        # the grids from the glove stream as written, read back from the closed file: a recording of any
        # length holds no glove history in memory
        grids = write_grids_from_glove(self.folder, self.layout, self.config) if has_glove else None
        if failure is not None:
            raise failure
        return grids

    def _put_in_place(self, names: list[str]) -> Exception | None:
        """Rename each stream's temporary file to its name (never over a file); the first failure, else None. A
        stream that cannot take its name stays under its temporary one, still marked, where readers find it."""
        failure = None
        for name in names:
            temporary = temporary_path(self.folder / name)
            try:
                rename_new(temporary, self.folder / name)
            except FileExistsError:
                failure = failure or UserError(f"{self.folder / name}: appeared while the episode was written; the "
                                               f"recorded stream is kept as {temporary.name}")
                continue
            except OSError as exc:
                failure = failure or OSError(exc.errno, exc.strerror, str(self.folder / name))
                continue
            unmark(temporary)
        try:
            if self.durable:
                fsync_path(self.folder, directory=True)
        except OSError as exc:
            failure = failure or exc
        return failure

    def _close_stream(self, name: str, handle: IO[str]) -> None:
        try:
            if self.durable and not handle.closed:
                handle.flush()
                fsync_fd(handle.fileno(), self.folder / name)
        finally:
            handle.close()

    def __enter__(self) -> RawEpisodeWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
