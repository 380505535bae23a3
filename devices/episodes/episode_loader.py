"""Find and open episodes: raw EgoTouch folders and HDF5 trajectories, alone or under a dataset root, and
any plain video (an ego-only episode without poses or pressure)."""
from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.hdf5_episode import open_hdf5_episode
from touchanything.devices.episodes.lerobot_episode import find_lerobot_episodes, open_lerobot_episode
from touchanything.devices.episodes.lerobot_format import is_lerobot_root, parse_address
from touchanything.devices.episodes.raw_episode import is_raw_episode, open_raw_episode
from touchanything.devices.episodes.video_io import VideoReader

HDF5_SUFFIXES = (".hdf5", ".h5")
MAX_DEPTH = 4
"""Trajectory folders are searched up to this many levels below a root (as the official converter does)."""


def is_hdf5_path(path: Path) -> bool:
    return Path(path).suffix.lower() in HDF5_SUFFIXES


def open_episode(path: Path) -> Episode:
    """Open a raw episode folder, an HDF5 trajectory file, an episode of a LeRobot dataset (`ROOT/episode_NNNNNN`,
    or the dataset's root when it holds one episode), or any other file as a plain video (`open_video_episode`)."""
    path = Path(path)
    if (address := parse_address(path)) is not None and not path.exists():
        return open_lerobot_episode(*address)
    if not path.exists():
        raise DataError(path, None, "not found")
    if path.is_dir():
        if is_lerobot_root(path):
            return _only_episode(path)
        if not is_raw_episode(path):
            raise DataError(path, None, "not an episode folder (no chest.mp4 or jq_pressure.json)")
        return open_raw_episode(path)
    if is_hdf5_path(path):
        return open_hdf5_episode(path)
    try:
        return open_video_episode(path)
    except DataError as exc:
        raise DataError(path, None, f"not an episode folder or .hdf5 file, and {exc.problem}") from None


def _only_episode(root: Path) -> Episode:
    """The episode of a LeRobot dataset that holds one; a dataset of several names how to open one."""
    episodes = find_lerobot_episodes(root)
    if len(episodes) != 1:
        raise DataError(root, None, f"a LeRobot dataset of {len(episodes)} episodes; open one as "
                        f"{fmt.episode_address(root, 0)} (… {fmt.episode_address(root, max(len(episodes) - 1, 0)).name})")
    return open_episode(episodes[0])


def episode_exists(path: Path) -> bool:
    """`path` exists, or names an episode of a LeRobot dataset (`ROOT/episode_NNNNNN`, which is no file)."""
    return Path(path).exists() or parse_address(Path(path)) is not None


def is_plain_video(episode: Episode) -> bool:
    """An episode opened by `open_video_episode` (a file that is neither a folder nor HDF5)."""
    return episode.path.is_file() and not is_hdf5_path(episode.path)


def open_video_episode(path: Path) -> Episode:
    """Any video PyAV reads as an episode: its frames as the ego view, at the file's frame rate (timestamps
    i / fps), no poses, gloves or pressure. DataError (one line) for a file that is not a readable video."""
    path = Path(path)
    try:
        reader = VideoReader(path)
    except DataError as exc:
        raise DataError(path, None, f"not a video PyAV can read: {exc.problem}") from None
    stamps = np.round(np.arange(reader.num_frames) * 1e6 / reader.fps).astype(np.int64)
    return Episode(path=path, scene="", task="video", trajectory_id=path.stem, num_frames=reader.num_frames,
                   views={"ego": reader}, timestamps_us=stamps, fps=reader.fps)


def _episode_levels(root: Path) -> Iterator[Path]:
    """Every folder under `root` (itself included) at most 4 levels deep, not looking inside raw episode folders
    nor hidden folders (a cache such as `.frame_cache`). Symbolic links to folders are followed; a folder's path is
    where its link stands, and a folder reached twice (two links, or a link loop) is met once."""
    level, seen = [Path(root)], set()
    for _ in range(MAX_DEPTH + 1):
        level = [p for p in level if _first_visit(p, seen)]
        yield from level
        level = sorted(c for p in level if not is_raw_episode(p) for c in p.iterdir() if c.is_dir() and not _hidden(c))


def find_raw_episodes(root: Path) -> list[Path]:
    """Raw episode folders under `root` (itself included), at most 4 levels deep, sorted (`_episode_levels`)."""
    return sorted(p for p in _episode_levels(root) if is_raw_episode(p))


def find_empty_folders(root: Path) -> list[Path]:
    """Folders under `root` (at most 4 levels deep) holding nothing but hidden entries, sorted: an episode folder
    whose files were never written, or lost. Hidden folders are not counted."""
    if not Path(root).is_dir():
        return []
    return sorted(p for p in _episode_levels(root) if not _hidden(p) and not any(not _hidden(c) for c in p.iterdir()))


def find_hdf5_files(root: Path) -> list[Path]:
    """HDF5 trajectory files under `root`, sorted; hidden folders below `root` (a cache such as `.frame_cache`,
    whose entries are HDF5 too) are not searched. Symbolic links to folders are followed (a file's path is
    where its link stands; a folder reached twice, by two links or a link loop, is read once)."""
    found, seen = [], set()
    for folder, subfolders, files in os.walk(root, followlinks=True):
        if not _first_visit(Path(folder), seen):
            subfolders.clear()
            continue
        subfolders[:] = [name for name in subfolders if not _hidden(Path(name))]
        found += [Path(folder) / name for name in files if is_hdf5_path(Path(name)) and (Path(folder) / name).is_file()]
    return sorted(found)


def _hidden(path: Path) -> bool:
    """A hidden file or folder: its name starts with a dot."""
    return path.name.startswith(".")


def _first_visit(folder: Path, seen: set[tuple[int, int]]) -> bool:
    """True the first time the real folder behind `folder` is met (recorded in `seen`); False after, or when
    it cannot be read."""
    try:
        status = folder.stat()
    except OSError:
        return False
    key = (status.st_dev, status.st_ino)
    if key in seen:
        return False
    seen.add(key)
    return True
