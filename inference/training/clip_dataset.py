"""Training clips: the official sampler (T = 8 frames at interval 2, non-overlapping starts 0, 15, 30, …),
pose rules and target preparation over HDF5 trajectories and raw episode folders, and the DataLoader that feeds
them.

Poses and pressure (small) are read once when the dataset is built. Frames come from a `FrameCache` (decoded
and resized once) when one is given — always for raw episode folders — else they are decoded and resized per
clip from the HDF5 file, inside the DataLoader's worker processes when there are any (`blank`: none is decoded;
every view shows black frames, the pose-only baseline). Without a cache a worker opens each trajectory's file on
first use and closes it when the worker exits; the main process opens a file per clip and closes it at once, so
no HDF5 handle is ever open in a process that forks workers.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from multiprocessing.util import Finalize
from pathlib import Path

import h5py
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset, DistributedSampler, get_worker_info

from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode_files import grids_normalized
from touchanything.devices.episodes.episode_loader import is_hdf5_path, open_episode
from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS
from touchanything.devices.episodes.raw_episode import is_raw_episode
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import blank_frames, resize_frame, to_model_input
from touchanything.inference.training.frame_cache import FrameCache


def clip_starts(frames: int, span: int) -> list[int]:
    """Non-overlapping starts 0, span, 2·span, … while start ≤ T − span (the tail is dropped)."""
    return list(range(0, frames - span + 1, span))


@dataclass
class EpisodeArrays:
    """One trajectory's HDF5 file, its readable views (official names, read per clip), prepared poses
    (T, 42, 3), pressure (T, 2, 21, 21) with NaN outside the layout, and whether it is stored normalised."""

    path: Path
    views: tuple[str, ...]
    poses: np.ndarray
    pressure: np.ndarray
    normalized: bool

    def cut(self, frames: int) -> EpisodeArrays:
        """The first `frames` frames (all when it holds fewer)."""
        return replace(self, poses=self.poses[:frames], pressure=self.pressure[:frames])


def episode_poses(episode, pose_source: str, fallback: str | None) -> np.ndarray | None:
    """Prepared (T, 42, 3) poses from `pose_source`; with a `fallback`, a hand invalid there takes the
    fallback's joints and validity in that frame (the official per-frame replacement). None: no such stream."""
    hands = episode.hands(pose_source)
    if hands is None:
        return None
    joints, valid = hands.joints.copy(), hands.valid.copy()
    other = episode.hands(fallback) if fallback else None
    if other is not None:
        replace = ~valid
        joints[replace], valid[replace] = other.joints[replace], other.valid[replace]
    return prepare_poses(joints.reshape(episode.num_frames, 42, 3), valid)


def load_episode(path: Path, pose_source: str, fallback: str | None = None) -> EpisodeArrays:
    """Everything of an HDF5 trajectory or a raw episode folder but its frames; UserError when it cannot be trained
    on. A raw episode is what `convert` would make of it: normalised when its grids lie in [0, 1]."""
    if not (is_hdf5_path(path) or is_raw_episode(path)):
        raise UserError(f"{path}: training reads HDF5 trajectories and raw episode folders")
    with open_episode(path) as episode:
        if episode.pressure is None:
            raise UserError(f"{path}: no pressure grids; cannot train on it")
        poses = episode_poses(episode, pose_source, fallback)
        if poses is None:
            raise UserError(f"{path}: no {pose_source} poses; cannot train on it")
        grids = episode.pressure.grids
        normalized = grids_normalized(grids) if Path(path).is_dir() else bool(episode.pressure.attrs.get("normalized", False))
        return EpisodeArrays(Path(path), episode.view_names, poses, grids.astype(np.float32), normalized)


def prepare_target(pressure: np.ndarray, normalized: bool) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2, 21, 21) with NaN → (target in [0, 1] with NaN → 0, sensor mask 1/0). Not normalised data
    are divided by max(nanmax, 1) of the clip, as the official loader does."""
    mask = ~np.isnan(pressure)
    values = np.where(mask, pressure, 0.0)
    vmax = 1.0 if normalized else max(float(values.max(initial=0.0)), 1.0)
    return np.clip(values / vmax, 0.0, 1.0).astype(np.float32), mask.astype(np.float32)


def _close_files(files: dict[int, h5py.File]) -> None:
    for file in files.values():
        file.close()
    files.clear()


class ClipDataset(Dataset):
    """Items: views {name: (T, 3, S, S)}, poses (T, 42, 3), target and mask (T, 2, 21, 21), the episode
    index and the frame indices (T,) — everything a training step and the feature cache need. Items depend
    only on the index (no random numbers are drawn), so any number of workers yields the same batches."""

    def __init__(self, files: list[Path], size: int, pose_source: str = "wilor", fallback: str | None = None,
                 blank: bool = False, cache: FrameCache | None = None, on_episode=None, workers: int = 1) -> None:
        """`cache`: frames from it (its missing entries built here in `workers` processes, before any loader worker
        starts); `on_episode()` is called after each trajectory is ready (a progress bar)."""
        self.cache = None if blank else cache
        if self.cache is None and not blank and (folder := next((f for f in files if Path(f).is_dir()), None)):
            raise UserError(f"{folder}: a raw episode folder trains from the frame cache, and there is none")
        self.episodes = []
        for f in files:
            self.episodes.append(load_episode(f, pose_source, fallback))
            if self.cache is None and on_episode:
                on_episode()
        if self.cache is not None:  # a raw episode's videos may decode fewer frames than they declare
            self.cache.build([(f, e.views) for f, e in zip(files, self.episodes)], workers, on_episode)
            self.episodes = [e.cut(self.cache.length(f, e.views)) for f, e in zip(files, self.episodes)]
        self.size, self.blank = size, blank
        self.offsets = np.arange(CLIP_LENGTH) * FRAME_INTERVAL
        self.items = [(e, s) for e, ep in enumerate(self.episodes) for s in clip_starts(len(ep.poses), SPAN)]
        self._files: dict[int, h5py.File] = {}  # filled only inside a DataLoader worker

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, index: int) -> dict:
        e, start = self.items[index]
        episode = self.episodes[e]
        frames = start + self.offsets
        target, mask = prepare_target(episode.pressure[frames], episode.normalized)
        return {
            "views": self._views(e, frames),
            "poses": torch.from_numpy(episode.poses[frames]),
            "target": torch.from_numpy(target), "mask": torch.from_numpy(mask),
            "episode": e, "frames": torch.from_numpy(frames),
        }

    def _views(self, e: int, frames: np.ndarray) -> dict[str, torch.Tensor]:
        """Resized and normalised frames of every view: from the frame cache, else decoded through this
        worker's open file or (in the main process) a file opened for this clip only. Blank: black frames,
        nothing read."""
        if self.blank:
            black = to_model_input(blank_frames((len(frames), self.size, self.size, 3)))
            return dict.fromkeys(self.episodes[e].views, black)
        if self.cache is not None:
            episode = self.episodes[e]
            clip = self.cache.clip(episode.path, episode.views, frames)
            return {view: to_model_input(clip[:, v]) for v, view in enumerate(episode.views)}
        if get_worker_info() is not None:
            return self._read(self._worker_file(e), e, frames)
        with h5py.File(self.episodes[e].path, "r") as file:
            return self._read(file, e, frames)

    def _read(self, file: h5py.File, e: int, frames: np.ndarray) -> dict[str, torch.Tensor]:
        views = {}
        for view in self.episodes[e].views:
            data = file[IMAGE_KEYS[view]]
            try:
                images = [resize_frame(data[i], self.size) for i in frames]
            except OSError as exc:
                raise UserError(f"{file.filename}: view {view}: frames {frames[0]}–{frames[-1]} unreadable ({exc})") from None
            views[view] = to_model_input(np.stack(images))
        return views

    def _worker_file(self, e: int) -> h5py.File:
        """This worker's handle on trajectory `e`, opened on first use and closed when the worker exits."""
        if not self._files:
            Finalize(self, _close_files, args=(self._files,), exitpriority=0)
        if e not in self._files:
            self._files[e] = h5py.File(self.episodes[e].path, "r")
        return self._files[e]


def clip_loader(dataset: ClipDataset, batch_size: int, num_workers: int, seed: int, shuffle: bool,
                pin_memory: bool = False, replicas: int = 1, rank: int = 0) -> DataLoader:
    """A loader kept for the whole run (workers persist across epochs); call `loader.sampler.set_epoch(e)`
    before each pass. The order is a permutation seeded by `seed + epoch` (this rank's share of it under
    DDP), whatever the number of workers; the loader draws its workers' seeds from its own generator, so
    it never consumes the global torch RNG (view dropout, dropout) — 0 and N workers train identically."""
    sampler = DistributedSampler(dataset, num_replicas=replicas, rank=rank, shuffle=shuffle, seed=seed)
    return DataLoader(dataset, batch_size=batch_size, sampler=sampler, num_workers=num_workers,
                      pin_memory=pin_memory, persistent_workers=num_workers > 0,
                      generator=torch.Generator().manual_seed(seed))
