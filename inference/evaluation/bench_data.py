"""Benchmark inputs: the held-out trajectories (a dataset root's split lists, or every episode under a folder),
decoded once (frames resized to the model input), a full-resolution clip for latency, and the process's
resident memory."""
from __future__ import annotations

import os
import resource
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError, failure_line
from touchanything.core.snapshot import Snapshot
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, read_split
from touchanything.devices.episodes.episode_loader import (
    episode_exists,
    find_hdf5_files,
    find_raw_episodes,
    is_hdf5_path,
    open_episode,
)
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.inference.model.preprocess import resize_frame


@dataclass
class BenchEpisode:
    """One episode in memory. images {view: (F, S, S, 3) uint8}; joints (F, 42, 3); valid (F, 2);
    gt (F, 2, 21, 21) metric-ready ground truth (NaN outside the layout); split: the held-out list it comes
    from (`test_seen`, `test_unseen`; `episodes` for a plain folder of episodes); path: where it was read."""

    name: str
    images: dict[str, np.ndarray]
    joints: np.ndarray
    valid: np.ndarray
    gt: np.ndarray
    split: str = "episodes"
    path: Path | None = None

    @property
    def num_frames(self) -> int:
        return len(self.joints)

    def snapshot(self, index: int, t_us: int) -> Snapshot:
        return Snapshot(index, t_us, {v: frames[index] for v, frames in self.images.items()}, self.joints[index],
                        self.valid[index])


HELD_OUT_SPLITS = ("test_seen", "test_unseen")
"""The split lists a dataset root's held-out trajectories come from by default."""
PLAIN_FOLDER = "episodes"
"""The stratum of every episode of a folder without a split file."""


def episode_paths(data: Path) -> list[Path]:
    """Raw episode folders and HDF5 files under `data` (or `data` itself)."""
    if not Path(data).exists():
        raise UserError(f"{data}: not found")
    if is_hdf5_path(data):
        return [Path(data)]
    paths = find_raw_episodes(data) + find_hdf5_files(data)
    if not paths:
        raise UserError(f"{data}: no episodes (raw EgoTouch folders or .hdf5 files) found")
    return paths


def held_out_paths(data: Path, splits: list[str] | None = None) -> list[tuple[Path, str]]:
    """(trajectory, split) pairs: the `splits` lists (default `HELD_OUT_SPLITS`) of DATA/split.json when DATA is a
    dataset root — its split file lists trajectories that exist —, else every episode under DATA with the split
    `episodes` (then `splits` is an error). A split file none of whose trajectories exists (a raw simulator root:
    it names the HDF5 files `convert` will write) leaves DATA a folder of episodes. UserError before any work for
    an unknown or empty list, or a dataset root that lists some trajectories that do not exist."""
    split_file = Path(data) / SPLIT_FILE
    lists = read_split(split_file) if split_file.is_file() else None
    if lists is not None and not any(episode_exists(p) for paths in lists.values() for p in paths):
        lists = None
    if lists is None:
        if splits:
            raise UserError(f"--splits needs a dataset root whose {SPLIT_FILE} lists its trajectories; {data} has none")
        return [(path, PLAIN_FOLDER) for path in episode_paths(data)]
    unknown = [name for name in splits or () if name not in SPLIT_KEYS]
    if unknown:
        raise UserError(f"unknown split {unknown[0]!r}; choose from {', '.join(SPLIT_KEYS)}")
    pairs = [(path, name) for name in splits or HELD_OUT_SPLITS for path in lists[name]]
    if not pairs:
        raise UserError(f"{split_file}: the {' and '.join(splits or HELD_OUT_SPLITS)} list(s) are empty")
    missing = [path for path, _ in pairs if not episode_exists(path)]
    if missing:
        raise UserError(f"{split_file}: {len(missing)} listed trajectories do not exist (the first: {missing[0]})")
    return pairs


def load_episode(path: Path, size: int, max_frames: int | None, split: str = PLAIN_FOLDER) -> BenchEpisode:
    with open_episode(path) as episode:
        if episode.pressure is None or episode.wilor is None:
            raise UserError(f"{path}: needs ground-truth pressure and WiLoR poses for the accuracy benchmark")
        frames = episode.num_frames if max_frames is None else min(max_frames, episode.num_frames)
        source = ReplaySource(episode, ReplayConfig(speed=None))
        images: dict[str, list] = {}
        for index in range(frames):
            for view, image in source.snapshot(index).images.items():
                images.setdefault(view, []).append(resize_frame(image, size))
        gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
        return BenchEpisode(f"{episode.scene}/{episode.task}/{episode.trajectory_id}",
                            {v: np.stack(f) for v, f in images.items()},
                            episode.wilor.joints[:frames].reshape(frames, 42, 3), episode.wilor.valid[:frames], gt[:frames],
                            split, Path(path))


def load_episodes(pairs: list[tuple[Path, str]], size: int, max_frames: int | None) -> tuple[list[BenchEpisode], list[str]]:
    """`load_episode` of every (path, split); one that fails (any exception) is named in the second list with its
    reason and the others are loaded (none may load)."""
    episodes, failures = [], []
    for path, split in pairs:
        try:
            episodes.append(load_episode(path, size, max_frames, split))
        except Exception as exc:  # noqa: BLE001 - one bad trajectory never stops the benchmark
            failures.append(failure_line(path, exc))
    return episodes, failures


def latency_clip(path: Path, frames: int) -> list[Snapshot]:
    """The first `frames` snapshots of an episode at full camera resolution (preprocessing is timed too)."""
    with open_episode(path) as episode:
        source = ReplaySource(episode, ReplayConfig(speed=None))
        return [source.snapshot(i) for i in range(min(frames, episode.num_frames))]


def first_latency_clip(paths: list[Path], frames: int) -> list[Snapshot]:
    """`latency_clip` of the first of `paths` that can be read (the failures are named by `load_episodes`)."""
    reasons = []
    for path in paths:
        try:
            return latency_clip(path, frames)
        except Exception as exc:  # noqa: BLE001 - any trajectory that reads serves for latency
            reasons.append(failure_line(path, exc))
    raise UserError(f"no episode could be read for the latency clip ({reasons[0]})")


def resident_mb() -> float:
    """Current resident memory of this process in MB (peak so far where /proc is unavailable)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1e6
    except (OSError, ValueError, IndexError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
