"""Training frames decoded and resized once per dataset, kept in files beside it and reused by content.

Every epoch reads the same frames; decoding them from gzip HDF5 chunks and resizing them is most of a small
model's step on the CPU. `FrameCache.clip(path, views, frames)` gives frames of a trajectory at the model's input
size, (N, V, S, S, 3) uint8 RGB in the order of `views`, resized exactly as the uncached path does
(`preprocess.resize_frame`), from `<root>/.frame_cache/<sha1 of the file>.<views>.<S>px.h5`: one dataset `frames`
(T, V, S, S, 3), a gzip-1 chunk per frame — about 3.3× smaller than the raw arrays (a 300-frame trajectory of three
views: 3.4 MB at 64 px), a clip of 8 frames read in about 1 ms.

- **HDF5 or raw:** a trajectory is an HDF5 file or a raw episode folder, whose videos are decoded as `convert`
  decodes them — so data too large to keep as HDF5 (93 MB per 10 s episode; the raw folder: 3 MB) train from
  their raw folders and the entries alone.
- **By content:** the file name is the SHA-1 of the trajectory's bytes (a raw folder's: of its videos), so a
  changed trajectory gets a new entry and an unchanged one (copied, renamed, converted again to the same bytes)
  reuses its entry. Digests are remembered in `index.json` by path, size and modification time (as git does),
  so a later run hashes only files whose size or time changed.
- **Atomic:** an entry is written under a marked temporary name (`core.temporary_files`) and renamed when
  complete; an interrupted build leaves no entry: its temporary file is removed at once, or, when the process was
  killed, by the next run that opens the cache (named on stderr).
- **Built once, in parallel:** entries are built under the folder's lock (`.build.lock`), so two trainings side by
  side on one dataset decode each trajectory once, the second waiting for the first's entries (said once on stderr);
  `build` decodes a run's missing entries in as many processes as the run has torch threads.
- **Per process:** entries are opened on first use in each process; a forked DataLoader worker opens its own
  and never reads through a handle it inherited.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.temporary_files import mark, remove_left_behind, temporary_path, unmark
from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS
from touchanything.devices.episodes.raw_episode import VIDEO_FILES, episode_file, open_raw_episode
from touchanything.inference.model.preprocess import resize_frame

CACHE_DIR = ".frame_cache"
INDEX = "index.json"
BUILD_LOCK = ".build.lock"
FRAMES = "frames"


def file_digest(path: Path) -> str:
    """SHA-1 of a file's bytes (hex)."""
    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha1").hexdigest()


@contextlib.contextmanager
def _view_images(path: Path, views: tuple[str, ...]) -> Iterator[tuple[int, Callable[[int, int], np.ndarray | None]]]:
    """(frame count, read(v, i) → (H, W, 3) uint8 RGB) of the `views` of an HDF5 trajectory or a raw episode folder
    (its videos, decoded as `convert` decodes them; a frame a video cannot decode reads None); UserError for an
    unreadable HDF5 frame or a missing video."""
    if Path(path).is_dir():
        with open_raw_episode(path) as episode:
            if missing := [view for view in views if view not in episode.views]:
                raise UserError(f"{path}: no readable {VIDEO_FILES[missing[0]]}; cannot train on its frames")
            sources = [episode.views[view] for view in views]
            yield min(s.num_frames for s in sources), lambda v, i: sources[v].read(i)
        return
    with h5py.File(path, "r") as file:
        images = [file[IMAGE_KEYS[view]] for view in views]

        def read(v: int, i: int) -> np.ndarray:
            try:
                return images[v][i]
            except OSError as exc:
                raise UserError(f"{path}: view {views[v]}: frame {i} unreadable ({exc})") from None

        yield min(len(d) for d in images), read


def write_entry(path: Path, views: tuple[str, ...], size: int, target: Path) -> None:
    """Every frame of `views` of a trajectory (HDF5 file or raw episode folder), resized, into a new HDF5 file
    `target`: dataset `frames` (T, V, S, S, 3) uint8, a gzip-1 chunk per frame. A video that decodes fewer frames
    than it declares ends the entry there, as `convert` cuts the trajectory."""
    shape = (len(views), size, size, 3)
    with _view_images(path, views) as (count, read), h5py.File(target, "w") as out:
        data = out.create_dataset(FRAMES, (count, *shape), np.uint8, chunks=(1, *shape), maxshape=(None, *shape),
                                  compression="gzip", compression_opts=1)
        frame = np.empty(shape, np.uint8)
        for i in range(count):
            images = [read(v, i) for v in range(len(views))]
            if any(image is None for image in images):
                data.resize(i, axis=0)
                break
            for v, image in enumerate(images):
                frame[v] = resize_frame(image, size)
            data[i] = frame


def _write_atomically(target: Path, write: Callable[[Path], None]) -> None:
    """`write(path)` creates a marked temporary file beside `target`, renamed to it when complete (removed on
    error)."""
    temporary = temporary_path(target)
    mark(temporary, "file")
    try:
        write(temporary)
    except BaseException:
        temporary.unlink(missing_ok=True)
        unmark(temporary)
        raise
    os.replace(temporary, target)
    unmark(temporary)


def _build_entry(path: Path, views: tuple[str, ...], size: int, target: Path) -> None:
    """Write the entry `target` of a trajectory's `views` at `size` px (in a worker process or in this one)."""
    _write_atomically(target, lambda temporary: write_entry(path, views, size, temporary))


class FrameCache:
    """Frames of trajectories (HDF5 files, raw episode folders) at `size` px under `folder` (`<root>/.frame_cache`)."""

    def __init__(self, folder: Path, size: int) -> None:
        self.folder, self.size = Path(folder), size
        self._index = self._read_index()
        self._paths: dict[Path, Path] = {}
        self._open: dict[Path, h5py.Dataset] = {}
        self._pid = os.getpid()
        self.built = self.reused = 0
        self._said_waiting = False

    @classmethod
    def beside(cls, root: Path, size: int) -> FrameCache:
        """The cache of the dataset at `root`; UserError when its folder cannot be created or written."""
        folder = Path(root) / CACHE_DIR
        try:
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.NamedTemporaryFile(dir=folder):
                pass
        except OSError as exc:
            raise UserError(f"{folder}: cannot write the frame cache ({exc.strerror})") from None
        remove_left_behind(folder)
        return cls(folder, size)

    def _read_index(self) -> dict:
        try:
            index = json.loads((self.folder / INDEX).read_text())
            return index if isinstance(index, dict) else {}
        except (OSError, ValueError):
            return {}

    def _write_index(self) -> None:
        text = json.dumps(self._index, indent=1, sort_keys=True)
        _write_atomically(self.folder / INDEX, lambda path: path.write_text(text))

    def digest(self, path: Path) -> str:
        """A trajectory's content: an HDF5 file's SHA-1, or for a raw episode folder the SHA-1 of its videos' names
        and SHA-1s (its frames' only source)."""
        path = Path(path)
        if not path.is_dir():
            return self._file_digest(path)
        videos = [file for name in (VIDEO_FILES[view] for view in VIEW_NAMES) if (file := episode_file(path, name)).is_file()]
        listing = "".join(f"{file.name} {self._file_digest(file)}\n" for file in videos)
        return hashlib.sha1(listing.encode()).hexdigest()

    def _file_digest(self, path: Path) -> str:
        """The file's SHA-1, from the index when its size and modification time are unchanged."""
        stat = Path(path).stat()
        key = str(Path(path).resolve())
        known = self._index.get(key)
        if isinstance(known, dict) and known.get("size") == stat.st_size and known.get("mtime_ns") == stat.st_mtime_ns:
            return str(known["sha1"])
        digest = file_digest(path)
        self._index[key] = {"size": stat.st_size, "mtime_ns": stat.st_mtime_ns, "sha1": digest}
        self._write_index()
        return digest

    def entry(self, path: Path, views: tuple[str, ...]) -> Path:
        """The cache file of a trajectory's `views` (an HDF5 file or a raw episode folder), built now when missing."""
        path = Path(path)
        if path not in self._paths:
            self.build([(path, views)])
        return self._paths[path]

    def build(self, trajectories: list[tuple[Path, tuple[str, ...]]], workers: int = 1,
              on_entry: Callable[[], None] | None = None) -> None:
        """Make sure every (trajectory, views) has its entry: the missing ones are decoded in `workers` processes
        (in this one when 1) under the folder's build lock; `on_entry()` is called as each one is there."""
        missing = []
        for path, views in trajectories:
            path = Path(path)
            target = self.folder / f"{self.digest(path)}.{'-'.join(views)}.{self.size}px.h5"
            if target.is_file():
                self._there(path, target, on_entry, built=False)
            else:
                missing.append((path, views, target))
        if not missing:
            return
        with self._building():
            for path, _, target in [m for m in missing if m[2].is_file()]:  # built by another run meanwhile
                self._there(path, target, on_entry, built=False)
            missing = [m for m in missing if not m[2].is_file()]
            if workers <= 1 or len(missing) == 1:
                for path, views, target in missing:
                    _build_entry(path, views, self.size, target)
                    self._there(path, target, on_entry, built=True)
                return
            with ProcessPoolExecutor(min(workers, len(missing)), mp_context=get_context("spawn")) as pool:
                futures = {pool.submit(_build_entry, path, views, self.size, target): (path, target)
                           for path, views, target in missing}
                try:
                    for future in as_completed(futures):
                        future.result()
                        self._there(*futures[future], on_entry, built=True)
                except BaseException:
                    pool.shutdown(cancel_futures=True)  # the entries in progress are finished, the rest not started
                    raise

    def _there(self, path: Path, target: Path, on_entry: Callable[[], None] | None, built: bool) -> None:
        """Record that `path`'s entry `target` exists (built now or found), and tell `on_entry`."""
        self._paths[path] = target
        self.built, self.reused = self.built + built, self.reused + (not built)
        on_entry and on_entry()

    @contextlib.contextmanager
    def _building(self) -> Iterator[None]:
        """Hold the folder's build lock: two trainings side by side on one dataset decode each trajectory once, the
        second waiting for the first's entry instead of decoding it again (released when the process ends)."""
        with open(self.folder / BUILD_LOCK, "a") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if not self._said_waiting:
                    self._said_waiting = True
                    tqdm.write(f"frame cache {self.folder}: another run is building entries; waiting for them "
                               "(reused, not decoded again)", file=sys.stderr)
                fcntl.flock(lock, fcntl.LOCK_EX)
            yield

    def clip(self, path: Path, views: tuple[str, ...], frames: np.ndarray) -> np.ndarray:
        """Frames `frames` (N,) of a trajectory → (N, V, S, S, 3) uint8, read through this process's handle."""
        if self._pid != os.getpid():  # a forked worker: handles inherited from the parent are never used
            self._open, self._pid = {}, os.getpid()
        path = Path(path)
        if path not in self._open:
            self._open[path] = h5py.File(self.entry(path, views), "r")[FRAMES]
        data = self._open[path]
        return np.stack([data[i] for i in frames])  # one read per frame: h5py's list indexing is ~30× slower

    def length(self, path: Path, views: tuple[str, ...]) -> int:
        """How many frames the trajectory's entry holds (a raw episode's: those its videos decode)."""
        with h5py.File(self.entry(path, views), "r") as entry:
            return len(entry[FRAMES])

    def __getstate__(self) -> dict:
        """Worker processes get the entry names, not the parent's open handles."""
        return {**self.__dict__, "_open": {}}
