"""`split.json` (train / val / test_seen / test_unseen): reading, writing, and the official split builder. The
HDF5 readers are imported where the builder uses them: `touchanything --help` loads this module."""
from __future__ import annotations

import json
import os
import random
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError, UserError, failure_line, require_fraction, require_seed
from touchanything.core.json_files import read_json_file
from touchanything.core.output_safety import write_text

SPLIT_KEYS = ("train", "val", "test_seen", "test_unseen")
SPLIT_FILE = "split.json"
"""The split's file name in a dataset root (raw or HDF5)."""


def read_split(path: Path) -> dict[str, list[Path]]:
    """Read a split file; relative paths are taken relative to the split file's folder."""
    path = Path(path)
    data = read_json_file(path)
    if not isinstance(data, dict):
        raise DataError(path, None, f"expected an object with keys {', '.join(SPLIT_KEYS)}")
    split = {}
    for key in SPLIT_KEYS:
        entries = data.get(key, [])
        if not isinstance(entries, list) or not all(isinstance(e, str) for e in entries):
            raise DataError(path, key, "expected a list of file paths")
        for number, entry in enumerate(entries, start=1):
            if problem := _path_problem(entry):
                raise DataError(path, key, f"entry {number} is not a usable file path ({problem})")
        split[key] = [(path.parent / e) if not Path(e).is_absolute() else Path(e) for e in entries]
    return split


def is_split_file(path: Path) -> bool:
    """`path` is named split.json or reads as a split file: an earlier output of `split`, which a new one
    replaces without --overwrite."""
    if Path(path).name == SPLIT_FILE:
        return True
    try:
        read_split(path)
    except (DataError, OSError):
        return False
    return True


def _path_problem(entry: str) -> str | None:
    """Why a split entry can be no file's path (checking it would raise instead of saying "not found")."""
    if not entry.strip():
        return "empty"
    if "\x00" in entry:
        return "a NUL character"
    try:
        parts = [os.fsencode(part) for part in Path(entry).parts]
    except UnicodeError:
        return "not encodable as a file name"
    if any(len(part) > 255 for part in parts) or len(os.fsencode(entry)) > 4095:
        return "name too long"
    return None


def write_split(path: Path, split: dict[str, list[Path]], absolute: bool = False) -> None:
    """Write a split file with paths relative to its folder (or absolute, as the official tool does)."""
    path = Path(path)
    base = path.parent.resolve()

    def name(p: Path) -> str:
        resolved = Path(p).resolve()
        return str(resolved) if absolute else os.path.relpath(resolved, base)

    write_text(path, json.dumps({key: [name(p) for p in split.get(key, [])] for key in SPLIT_KEYS}, indent=1) + "\n")


@dataclass(frozen=True)
class SplitConfig:
    """The official defaults: seed 42, 5 % of each scene's tasks unseen, ≥ 30 frames, ≥ 30 % pose-valid."""

    seed: int = 42
    unseen_ratio: float = 0.05
    min_frames: int = 30
    min_wilor_valid: float = 0.3


def check_split_config(config: SplitConfig) -> None:
    """UserError naming the setting when a threshold or the seed is outside its domain (NaN included)."""
    require_seed("--seed", config.seed)
    if not 0.0 <= config.unseen_ratio < 1.0:
        raise UserError(f"--unseen-ratio must be a number in [0, 1), got {config.unseen_ratio}")
    require_fraction("--min-wilor-valid", config.min_wilor_valid)
    if config.min_frames < 0:
        raise UserError(f"--min-frames must be at least 0, got {config.min_frames}")


def empty_split_problem(split: dict[str, list[Path]], excluded: dict[Path, str]) -> str | None:
    """Why a split cannot be trained and tested on (an empty train list, or no test trajectory), or None."""
    empty = [name for name, lists in (("train", ("train",)), ("test", ("test_seen", "test_unseen")))
             if not any(split.get(key) for key in lists)]
    if not empty:
        return None
    kept = sum(len(split.get(key, [])) for key in SPLIT_KEYS)
    return f"the {' and '.join(empty)} list(s) would be empty ({kept} trajectories kept, {len(excluded)} excluded)"


def quality_problem(path: Path, config: SplitConfig) -> str | None:
    """Why a trajectory fails the quality filter, or None. Pose-valid = at least one valid WiLoR hand. A
    trajectory that cannot be read (any error) is excluded with the reason, naming the dataset or attribute."""
    import h5py

    from touchanything.devices.episodes.hdf5_episode import IMAGE_KEYS, WILOR_VALID_KEYS, frame_count, read_dataset

    try:
        with h5py.File(path, "r") as file:
            frames = frame_count(file)
            valid = np.stack([read_dataset(file, k, (), "iub") for k in WILOR_VALID_KEYS], axis=1).astype(bool)
            short = [f"{key} holds {file[key].shape[0]} frames" for key in IMAGE_KEYS.values()
                     if key in file and file[key].shape[0] < frames]
    except DataError as exc:
        return f"unreadable ({exc.field + ': ' if exc.field else ''}{exc.problem})"
    except Exception as exc:  # noqa: BLE001 - h5py raises many kinds for damaged files; each excludes the file
        return f"unreadable ({failure_line(path, exc).removeprefix(f'{path}: ')})"
    if short:
        return f"{short[0]} but metadata num_frames is {frames}"
    if frames < config.min_frames:
        return f"{frames} frames < {config.min_frames}"
    ratio = float(valid.any(axis=1).mean()) if len(valid) else 0.0
    return None if ratio >= config.min_wilor_valid else f"WiLoR valid ratio {ratio:.2f} < {config.min_wilor_valid}"


def build_split(hdf5_root: Path, config: SplitConfig = SplitConfig()) -> tuple[dict[str, list[Path]], dict[Path, str]]:
    """The official algorithm: unseen tasks per scene, then a seeded shuffle into test_seen / val / train.

    Files are `<root>/<Scene>/<Task>/<id>.hdf5`. Returns the split and the excluded files with reasons.
    """
    from touchanything.devices.episodes.episode_loader import find_hdf5_files

    check_split_config(config)
    files = find_hdf5_files(hdf5_root)
    if not files:
        raise UserError(f"{hdf5_root}: no .hdf5 trajectories found")
    excluded = {f: reason for f in files if (reason := quality_problem(f, config))}
    kept = [f for f in files if f not in excluded]
    rng = random.Random(config.seed)
    tasks_by_scene: dict[str, set[str]] = {}
    for f in kept:
        tasks_by_scene.setdefault(f.parent.parent.name, set()).add(f"{f.parent.parent.name}/{f.parent.name}")
    unseen: set[str] = set()
    for scene in sorted(tasks_by_scene):
        tasks = sorted(tasks_by_scene[scene])
        if len(tasks) >= 2:
            rng.shuffle(tasks)
            unseen.update(tasks[: max(1, int(len(tasks) * config.unseen_ratio))])
    split = partition_seen([f for f in kept if f"{f.parent.parent.name}/{f.parent.name}" not in unseen], rng)
    split["test_unseen"] = sorted(f for f in kept if f"{f.parent.parent.name}/{f.parent.name}" in unseen)
    return split, excluded


def partition_seen(items: list, rng: random.Random) -> dict[str, list]:
    """The official seen partition: shuffle, then test_seen = first max(1, int(N · 0.1)), val = next
    max(1, int((N − n_ts) / 9)), train = the rest (each list sorted)."""
    items = list(items)
    rng.shuffle(items)
    n_seen = max(1, int(len(items) * 0.1))
    n_val = max(1, int((len(items) - n_seen) / 9))
    return {"train": sorted(items[n_seen + n_val:]), "val": sorted(items[n_seen:n_seen + n_val]),
            "test_seen": sorted(items[:n_seen])}
