"""Find and open episodes: raw EgoTouch folders and HDF5 trajectories, alone or under a dataset root."""
from __future__ import annotations

from pathlib import Path

from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.hdf5_episode import open_hdf5_episode
from touchanything.devices.episodes.raw_episode import is_raw_episode, open_raw_episode
from touchanything.devices.errors import DataError

HDF5_SUFFIXES = (".hdf5", ".h5")
MAX_DEPTH = 4
"""Trajectory folders are searched up to this many levels below a root (as the official converter does)."""


def is_hdf5_path(path: Path) -> bool:
    return Path(path).suffix.lower() in HDF5_SUFFIXES


def open_episode(path: Path) -> Episode:
    """Open a raw episode folder or an HDF5 trajectory file."""
    path = Path(path)
    if not path.exists():
        raise DataError(path, None, "not found")
    if path.is_dir():
        if not is_raw_episode(path):
            raise DataError(path, None, "not an episode folder (no chest.mp4 or jq_pressure.json)")
        return open_raw_episode(path)
    if is_hdf5_path(path):
        return open_hdf5_episode(path)
    raise DataError(path, None, "not an episode (expected a raw episode folder or an .hdf5 file)")


def find_raw_episodes(root: Path) -> list[Path]:
    """Raw episode folders under `root` (itself included), at most 4 levels deep, sorted."""
    root = Path(root)
    found, level = [], [root]
    for _ in range(MAX_DEPTH + 1):
        found += [p for p in level if is_raw_episode(p)]
        level = sorted(c for p in level if not is_raw_episode(p) for c in p.iterdir() if c.is_dir())
    return sorted(found)


def find_hdf5_files(root: Path) -> list[Path]:
    """HDF5 trajectory files under `root`, sorted."""
    return sorted(p for p in Path(root).rglob("*") if p.is_file() and is_hdf5_path(p))
