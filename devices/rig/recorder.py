"""The recorder: Snapshots into a raw EgoTouch episode folder, written by a background thread.

`write(snapshot)` never blocks: it puts the Snapshot into a bounded queue, and when the queue is full the
Snapshot is dropped and counted (a slow disk costs frames, never the caller's time). One writer thread
turns each Snapshot into an `EpisodeFrame` for `RawEpisodeWriter`:

| Snapshot | episode file |
|---|---|
| `images[view]` | `chest.mp4` / `left.mp4` / `right.mp4` (H.264, fragmented MP4) |
| `joints`, `joints_valid` (the model's input, head-camera frame) | `wilor_hands.json` |
| `mocap_joints`, `mocap_valid` (when the rig has mocap) | `rokoko_hands.json` |
| `pressure_raw`, `glove_present`, `imu_wxyz`, `t_us` | `jq_pressure.json` (an absent glove is `null`) |
| `trackers` (when there are any) | `vive_poses.json` |

`stop()` writes what is queued, closes the files and computes `pressure_grids.npz` from the glove stream.
Crash safety is the writer's: JSONL rows are flushed per row and the videos are fragmented MP4, so a
recording whose process dies keeps everything but its last second (the grids are then missing:
`touchanything grids FOLDER` computes them from `jq_pressure.json`). Against a crash of the machine (power
loss, kernel panic) the writer thread fsyncs every file of the recording and, when files or folders were
created, their directories, every `fsync_s` seconds (`RecorderConfig.fsync_s`, default 1 s; 0: after every
frame; None: never) and at `stop()`, so a power loss loses at most the last `fsync_s` of each stream plus
the video fragment being encoded. A sync falls due after a frame is written, or while no frame comes
(the writer waits for the queue only until then). A writer error (disk full, permission, a failed fsync)
stops the writing; the files are still closed, the error shows in `status()` and `stop()` raises it as a
UserError, and everything written before it stays readable.
"""
from __future__ import annotations

import math
import queue
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.snapshot import TRACKER_ROLES, Snapshot
from touchanything.devices.episodes.episode_streams import IDENTITY_WXYZ
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.raw_episode import VIDEO_FILES, episode_file, is_raw_episode
from touchanything.devices.episodes.video_io import VideoReader

_STOP = object()
LIVE_PRESET = "ultrafast"
"""x264 preset for live recording: three 640×480 views plus the JSON streams reached 22 frames/s with
`veryfast` on 2 cores (short of the rig's 30); `ultrafast` keeps up (files about 2.4× larger)."""
"""Queued by `stop()` after the last Snapshot."""


@dataclass(frozen=True)
class RecorderConfig:
    """folder: the episode folder to create (`<root>/<Scene>/<task>/<trajectory_id>` to be found by the
    dataset tools). queue_frames: Snapshots waiting for the writer before new ones are dropped.
    fsync_s: seconds between fsyncs of every file of the recording (0: after every frame; None: never, the
    OS writes back when it chooses, about 30 s on Linux)."""

    folder: Path
    queue_frames: int = 60
    fsync_s: float | None = 1.0

    def __post_init__(self) -> None:
        if self.queue_frames < 1:
            raise UserError(f"recorder queue must hold at least 1 frame, got {self.queue_frames}")
        if not valid_fsync_s(self.fsync_s):
            raise UserError(f"recorder fsync_s must be a number of seconds ≥ 0 (0: after every frame) or None "
                            f"(never), got {self.fsync_s!r}")


def replayable_frames(folder: Path) -> int:
    """How many frames of the recording in `folder` can replay: the fewest of its videos' frames, as the episode
    reader aligns them (0 when the head camera's video is missing, does not open or its first frame does not
    decode). Only the videos are read: another stream of a failed recording may be anything (a device file, a
    cut line)."""
    counts = {view: _video_frames(episode_file(folder, name)) for view, name in VIDEO_FILES.items()
              if view == "ego" or episode_file(folder, name).exists()}
    return min(counts.values()) if counts["ego"] else 0


def _video_frames(path: Path) -> int:
    """The frames of a video as its reader counts them; 0 when it does not open or its first frame does not
    decode."""
    try:
        reader = VideoReader(path)
    except Exception:  # noqa: BLE001 - a video cut short by a failure may be unreadable in any way
        return 0
    try:
        return reader.num_frames if reader.read(0) is not None else 0
    except Exception:  # noqa: BLE001 - as above
        return 0
    finally:
        reader.close()


def valid_fsync_s(value: object) -> bool:
    """None, or a finite number of seconds ≥ 0 (not a bool)."""
    return value is None or (isinstance(value, int | float) and not isinstance(value, bool)
                             and math.isfinite(value) and value >= 0)


@dataclass(frozen=True)
class RecorderCounters:
    """written: frames in the episode; dropped: Snapshots not queued (queue full, or not recording);
    failed: Snapshots not written because of a writer error; queued: waiting now."""

    written: int = 0
    dropped: int = 0
    failed: int = 0
    queued: int = 0


def episode_frame(snapshot: Snapshot) -> EpisodeFrame:
    """The EpisodeFrame that records `snapshot` (see the module's table)."""
    frame = EpisodeFrame(images=snapshot.images, wilor=(snapshot.joints.reshape(2, 21, 3), snapshot.joints_valid),
                         timestamp_us=snapshot.t_us)
    if snapshot.mocap_joints is not None and snapshot.mocap_valid is not None:
        frame.rokoko = (snapshot.mocap_joints.reshape(2, 21, 3), snapshot.mocap_valid)
    if snapshot.pressure_raw is not None:
        present = np.ones(2, bool) if snapshot.glove_present is None else snapshot.glove_present
        quat = np.tile(np.float32(IDENTITY_WXYZ), (2, 1)) if snapshot.imu_wxyz is None else snapshot.imu_wxyz
        frame.glove = (snapshot.pressure_raw, present, quat)
    if snapshot.trackers:
        poses = np.zeros((len(TRACKER_ROLES), 7), np.float32)
        valid = np.zeros(len(TRACKER_ROLES), bool)
        for r, role in enumerate(TRACKER_ROLES):
            if role in snapshot.trackers:
                poses[r], valid[r] = snapshot.trackers[role], True
        frame.trackers = (poses, valid)
    return frame


def describe_error(exc: Exception) -> str:
    """One line: the OS reason and file for an OSError, a user error's own line, else the exception's type and text."""
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.strerror} ({exc.filename})" if exc.filename else exc.strerror
    return str(exc) if isinstance(exc, UserError) else f"{type(exc).__name__}: {exc}"


class Recorder:
    """Records one episode: `start()`, `write(snapshot)` from any thread (e.g. `clock.subscribe(recorder.write)`),
    `stop()`. Also `with Recorder(config) as recorder:`."""

    def __init__(self, config: RecorderConfig) -> None:
        self.config = config
        self._queue: queue.Queue = queue.Queue(maxsize=config.queue_frames)
        self._lock = threading.Lock()
        self._accepting = False
        self._counters = RecorderCounters()
        self._error: str | None = None
        self._thread: threading.Thread | None = None

    @property
    def is_recording(self) -> bool:
        return self._thread is not None

    def start(self) -> None:
        """Create the folder and start the writer; UserError when the folder already holds an episode or
        cannot be created."""
        if self.is_recording:
            raise RuntimeError("the recorder is already recording")
        folder = Path(self.config.folder)
        if folder.is_dir() and is_raw_episode(folder):
            raise UserError(f"{folder} already holds a recording; choose a new folder")
        writer = RawEpisodeWriter(folder, preset=LIVE_PRESET, durable=self.config.fsync_s is not None)
        with self._lock:
            self._counters, self._error = RecorderCounters(), None
            self._queue, self._accepting = queue.Queue(maxsize=self.config.queue_frames), True
        # The first fsync period starts here, before the thread does: a writer thread that starts late (a busy
        # CPU) must not push the first sync of the frames queued meanwhile further out than `fsync_s`.
        started = time.monotonic()
        self._thread = threading.Thread(target=self._run, args=(writer, started), name="recorder", daemon=True)
        self._thread.start()

    def write(self, snapshot: Snapshot) -> None:
        """Queue `snapshot` for writing; never blocks (a full queue, or a stopped recorder, drops it)."""
        with self._lock:
            if self._accepting:
                try:
                    self._queue.put_nowait(snapshot)
                    return
                except queue.Full:
                    pass
            self._counters = replace(self._counters, dropped=self._counters.dropped + 1)

    def stop(self) -> RecorderCounters:
        """Write what is queued, close the files (computing the grids); UserError if writing failed."""
        if self._thread is not None:
            with self._lock:
                self._accepting = False
            self._queue.put(_STOP)
            self._thread.join()
            self._thread = None
        counters = self.counters
        if self._error is not None:
            kept = min(replayable_frames(self.config.folder), counters.written)
            raise UserError(f"recording {self.config.folder} failed: {self._error}; " + (
                f"{kept} of the {counters.written} frames written before replay" if kept else
                f"none of the {counters.written} frames written before can be replayed (no frame of the head camera's "
                "video decodes)"))
        return counters

    def __enter__(self) -> Recorder:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def counters(self) -> RecorderCounters:
        with self._lock:
            return replace(self._counters, queued=self._queue.qsize())

    @property
    def is_behind(self) -> bool:
        """More than a quarter of the queue waits for the writer (0.5 s at 30 Hz with the default 60 frames):
        an owner that can drop work (the live engine) should leave the CPU to the writer until it catches up."""
        return self._queue.qsize() > self.config.queue_frames // 4

    @property
    def error(self) -> str | None:
        """The writer error that stopped the recording, or None."""
        return self._error

    def status(self) -> str:
        """One line, e.g. "recording /data/ep: 300 frames, 0 dropped, queue 2/60, 12.3 MB"."""
        c = self.counters
        state = f"recording {self.config.folder}" if self.is_recording else f"stopped {self.config.folder}"
        line = f"{state}: {c.written} frames, {c.dropped} dropped, queue {c.queued}/{self.config.queue_frames}"
        line += f", {self._bytes_on_disk() / 1e6:.1f} MB"
        return line + (f", failed: {self._error} ({c.failed} frames lost)" if self._error else "")

    def _bytes_on_disk(self) -> int:
        try:
            return sum(p.stat().st_size for p in Path(self.config.folder).iterdir() if p.is_file())
        except OSError:
            return 0

    def _run(self, writer: RawEpisodeWriter, started: float) -> None:
        """Writer thread: write each queued Snapshot until `_STOP`, fsyncing every `fsync_s` seconds (the first
        period from `started`, when `start()` ran) while something is unsynced (also when no Snapshot comes), then
        close the episode (fsyncing it)."""
        every = self.config.fsync_s
        last_sync, unsynced = started, False
        while True:
            syncing = every is not None and unsynced and self._error is None  # no syncs after an error
            wait = max(0.0, last_sync + every - time.monotonic()) if syncing else None
            try:
                snapshot = self._queue.get(timeout=wait)
            except queue.Empty:
                snapshot = None  # a sync is due and no Snapshot came
            if snapshot is _STOP:
                break
            if snapshot is not None:
                if self._error is not None:
                    self._count(failed=1)
                    continue
                try:
                    self._write_frame(writer, snapshot)
                except Exception as exc:  # noqa: BLE001 - any writer failure is kept, shown and raised by stop()
                    self._fail(exc)
                    self._count(failed=1)
                    continue
                self._count(written=1)
                unsynced = True
            if every is not None and unsynced and self._error is None and time.monotonic() - last_sync >= every:
                try:
                    self._sync(writer)
                except Exception as exc:  # noqa: BLE001 - as above
                    self._fail(exc)
                last_sync, unsynced = time.monotonic(), False
        try:
            writer.close()
        except Exception as exc:  # noqa: BLE001 - as above
            self._fail(exc)

    def _write_frame(self, writer: RawEpisodeWriter, snapshot: Snapshot) -> None:
        """Writer thread: one Snapshot into the episode (handed to the OS, not yet synced)."""
        writer.write(episode_frame(snapshot))

    def _sync(self, writer: RawEpisodeWriter) -> None:
        """Writer thread: fsync every file and the new directory entries."""
        writer.sync()

    def _count(self, written: int = 0, failed: int = 0) -> None:
        with self._lock:
            c = self._counters
            self._counters = replace(c, written=c.written + written, failed=c.failed + failed)

    def _fail(self, exc: Exception) -> None:
        with self._lock:
            self._error = self._error or describe_error(exc)
