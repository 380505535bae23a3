"""A data set where only the cameras tell touch: for tests of the pose-only baseline.

Each frame is in contact or not (blocks of 6–14 frames, drawn per episode). In contact every camera shows a
bright frame and the glove a strong press; out of contact the frames are dark and the glove idle. The hand
pose is drawn independently of contact, so it carries nothing: a model can only learn touch from the images.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.dataset_conversion import convert_dataset
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter

BRIGHT, DARK = 220, 25


def contact_sequence(frames: int, rng: np.random.Generator) -> np.ndarray:
    """(frames,) bool: alternating blocks of 6–14 frames, starting in contact or not at random."""
    flags, state = [], bool(rng.integers(2))
    while len(flags) < frames:
        flags += [state] * int(rng.integers(6, 15))
        state = not state
    return np.array(flags[:frames])


def vision_frame(contact: bool, rng: np.random.Generator, size: tuple[int, int]) -> dict[str, np.ndarray]:
    """Every view: a bright (contact) or dark frame with a little noise."""
    level = BRIGHT if contact else DARK
    return {v: np.clip(level + rng.integers(-10, 11, size=(*size, 3)), 0, 255).astype(np.uint8) for v in VIEW_NAMES}


def write_vision_episode(folder: Path, frames: int, seed: int, size: tuple[int, int] = (48, 64)) -> None:
    rng = np.random.default_rng(seed)
    contact = contact_sequence(frames, rng)
    quat = np.tile(np.array([1.0, 0.0, 0.0, 0.0], np.float32), (2, 1))
    with RawEpisodeWriter(folder, crf=10) as writer:
        for i in range(frames):
            joints = rng.uniform(-3, 3, size=(2, 21, 3)).astype(np.float32)
            joints[..., 2] += 50
            raw = rng.integers(0, 4, size=(2, 256))
            raw[:, 0:60] += 200 if contact[i] else 0
            writer.write(EpisodeFrame(images=vision_frame(bool(contact[i]), rng, size),
                                      wilor=(joints, np.array([True, True])),
                                      glove=(raw.astype(np.uint8), np.array([True, True]), quat)))


def write_vision_dataset(root: Path, episodes: int = 4, frames: int = 75) -> Path:
    """Raw episodes under root/raw, converted to root/h5 with a split.json that trains on all but the last
    episode and tests (and validates) on the last; returns root/h5."""
    for e in range(episodes):
        write_vision_episode(root / "raw" / "Lab" / "flash" / f"2026010{e}_000000_000", frames, seed=100 + e)
    out = root / "h5"
    convert_dataset(root / "raw", out, compression_level=1)
    files = sorted(str(p.relative_to(out)) for p in out.rglob("*.hdf5"))
    split = {"train": files[:-1], "val": files[-1:], "test_seen": files[-1:], "test_unseen": []}
    (out / "split.json").write_text(json.dumps(split))
    return out
