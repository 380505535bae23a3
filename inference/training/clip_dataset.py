"""Training clips: the official sampler (T = 8 frames at interval 2, non-overlapping starts 0, 15, 30, …),
pose rules and target preparation, over HDF5 trajectories held in memory at the model's input size."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.errors import UserError
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import resize_frame, to_model_input


def clip_starts(frames: int, span: int) -> list[int]:
    """Non-overlapping starts 0, span, 2·span, … while start ≤ T − span (the tail is dropped)."""
    return list(range(0, frames - span + 1, span))


@dataclass
class EpisodeArrays:
    """One trajectory: resized frames {view: (T, S, S, 3) uint8}, prepared poses (T, 42, 3), pressure
    (T, 2, 21, 21) with NaN outside the layout, and whether it is stored normalised."""

    path: Path
    images: dict[str, np.ndarray]
    poses: np.ndarray
    pressure: np.ndarray
    normalized: bool


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


def load_episode(path: Path, size: int, pose_source: str, fallback: str | None = None) -> EpisodeArrays:
    with open_episode(path) as episode:
        if episode.pressure is None:
            raise UserError(f"{path}: no pressure grids; cannot train on it")
        poses = episode_poses(episode, pose_source, fallback)
        if poses is None:
            raise UserError(f"{path}: no {pose_source} poses; cannot train on it")
        images = {}
        for view, source in episode.views.items():
            frames = [source.read(i) for i in range(episode.num_frames)]
            if any(f is None for f in frames):
                raise UserError(f"{path}: view {view} has unreadable frames")
            images[view] = np.stack([resize_frame(f, size) for f in frames])
        normalized = bool(episode.pressure.attrs.get("normalized", False))
        return EpisodeArrays(Path(path), images, poses, episode.pressure.grids.astype(np.float32), normalized)


def prepare_target(pressure: np.ndarray, normalized: bool) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2, 21, 21) with NaN → (target in [0, 1] with NaN → 0, sensor mask 1/0). Not normalised data
    are divided by max(nanmax, 1) of the clip, as the official loader does."""
    mask = ~np.isnan(pressure)
    values = np.where(mask, pressure, 0.0)
    vmax = 1.0 if normalized else max(float(values.max(initial=0.0)), 1.0)
    return np.clip(values / vmax, 0.0, 1.0).astype(np.float32), mask.astype(np.float32)


class ClipDataset(Dataset):
    """Items: views {name: (T, 3, S, S)}, poses (T, 42, 3), target and mask (T, 2, 21, 21), the episode
    index and the frame indices (T,) — everything a training step and the feature cache need."""

    def __init__(self, files: list[Path], size: int, pose_source: str = "wilor", fallback: str | None = None) -> None:
        self.episodes = [load_episode(f, size, pose_source, fallback) for f in files]
        self.offsets = np.arange(CLIP_LENGTH) * FRAME_INTERVAL
        self.items = [(e, s) for e, ep in enumerate(self.episodes) for s in clip_starts(len(ep.poses), SPAN)]

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, index: int) -> dict:
        e, start = self.items[index]
        episode = self.episodes[e]
        frames = start + self.offsets
        target, mask = prepare_target(episode.pressure[frames], episode.normalized)
        return {
            "views": {v: to_model_input(images[frames]) for v, images in episode.images.items()},
            "poses": torch.from_numpy(episode.poses[frames]),
            "target": torch.from_numpy(target), "mask": torch.from_numpy(mask),
            "episode": e, "frames": torch.from_numpy(frames),
        }
