"""Convert raw EgoTouch episode folders to HDF5 trajectories in the official schema.

Output: `<out>/<Scene>/<Task>/<trajectory_id>.hdf5`, written to a temporary file and renamed when complete
(output_safety.replacing), so a failed or interrupted conversion never leaves a half-written trajectory behind.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from touchanything.core.errors import DataError, failure_line
from touchanything.devices.episodes.episode import Episode, problems_in_brief
from touchanything.devices.episodes.episode_files import MAXIMA_KEYS, grids_normalized, read_masks, read_quality
from touchanything.devices.episodes.hdf5_episode import (
    GRID_KEYS,
    IMAGE_KEYS,
    MASK_KEYS,
    ROKOKO_KEYS,
    TRACKER_KEYS,
    WILOR_KEYS,
    WILOR_VALID_KEYS,
)
from touchanything.devices.episodes.hdf5_output import hdf5_output
from touchanything.devices.episodes.raw_episode import (
    GRIDS_FILE,
    MASKS_FILE,
    QUALITY_FILE,
    REQUIRED_FILES,
    VIDEO_FILES,
    WILOR_FILE,
    open_raw_episode,
)

CONVERTER = "touchanything convert"
"""The completion mark's value in the trajectories `convert` writes (`hdf5_output`)."""
DUPLICATE_ISSUE_RATIO = 0.20


@dataclass
class ConversionResult:
    """status: converted | skipped | failed. damage: what a converted trajectory lacks or left out, one line (None
    when the episode was whole): the trajectory holds what could be read, the rest marked invalid or cut."""

    source: Path
    output: Path
    status: str
    frames: int = 0
    seconds: float = 0.0
    problems: list[str] = field(default_factory=list)
    error: str | None = None
    quality: dict = field(default_factory=dict)
    damage: str | None = None


def output_path(folder: Path, raw_root: Path, out_root: Path) -> Path:
    """`<out>/<Scene>/<Task>/<trajectory_id>.hdf5` mirroring the folder's place under the raw root: where it
    stands, so an episode folder that is a symbolic link to elsewhere keeps its place (no links are resolved)."""
    rel = Path(os.path.abspath(folder)).relative_to(os.path.abspath(raw_root))
    if rel == Path("."):
        return Path(out_root) / f"{Path(folder).name}.hdf5"
    return Path(out_root) / rel.parent / f"{rel.name}.hdf5"


def _gzip(level: int) -> dict:
    return {"compression": "gzip", "compression_opts": level} if level > 0 else {}


def _write_images(file: h5py.File, episode: Episode, level: int) -> dict[str, int]:
    """Stream every view into its dataset, cut to the frames all views could decode; returns how many each did."""
    decoded = {}
    for view, key in IMAGE_KEYS.items():
        source = episode.views[view]
        shape = (episode.num_frames, source.height, source.width, 3)
        data = file.create_dataset(key, shape=shape, maxshape=(None,) + shape[1:], dtype=np.uint8,
                                   chunks=(1,) + shape[1:], **_gzip(level))
        count = 0
        while count < episode.num_frames and (image := source.read(count)) is not None:
            data[count] = image
            count += 1
        decoded[view] = count
    for key in IMAGE_KEYS.values():
        file[key].resize(min(decoded.values()), axis=0)
    return decoded


def _write_streams(file: h5py.File, episode: Episode, frames: int, level: int) -> None:
    file.create_dataset("timestamps", data=episode.timestamps_us[:frames].astype(np.int64))
    for h, key in enumerate(GRID_KEYS):
        file.create_dataset(key, data=episode.pressure.grids[:frames, h], **_gzip(level))
    for h in range(2):
        file.create_dataset(WILOR_KEYS[h], data=episode.wilor.joints[:frames, h])
        file.create_dataset(WILOR_VALID_KEYS[h], data=episode.wilor.valid[:frames, h].astype(np.uint8))
        rokoko = episode.rokoko.joints[:frames, h] if episode.rokoko else np.zeros((frames, 21, 3), np.float32)
        file.create_dataset(ROKOKO_KEYS[h], data=rokoko)
    for r, key in enumerate(TRACKER_KEYS):
        poses = episode.trackers.poses[:frames, r] if episode.trackers else np.zeros((frames, 7), np.float32)
        file.create_dataset(key, data=poses)


def _write_masks(file: h5py.File, episode: Episode, frames: int, level: int, problems: list[str]) -> None:
    chest = episode.views["ego"]
    masks = np.zeros((frames, 0, chest.height, chest.width), np.uint8)
    obj_ids, valid = np.zeros((frames, 0), np.int32), np.zeros(frames, bool)
    if (episode.path / MASKS_FILE).exists():
        try:
            found = read_masks(episode.path / MASKS_FILE)
            if found.masks.shape[0] >= frames:
                masks, obj_ids, valid = found.masks[:frames], found.obj_ids[:frames], found.valid_frames[:frames]
            else:
                problems.append(f"{episode.path / MASKS_FILE}: masks: {found.masks.shape[0]} frames for {frames}; stored empty")
        except DataError as exc:
            problems.append(str(exc))
    file.create_dataset(MASK_KEYS[0], data=masks, **_gzip(level))
    file.create_dataset(MASK_KEYS[1], data=obj_ids)
    file.create_dataset(MASK_KEYS[2], data=valid)
    file["masks"].attrs.update(num_objects=masks.shape[1], mask_available=masks.shape[1] > 0,
                               valid_frame_count=int(valid.sum()))


def _write_attrs(file: h5py.File, episode: Episode, frames: int, quality: dict) -> None:
    chest = episode.views["ego"]
    file.create_group("metadata").attrs.update(
        trajectory_id=episode.trajectory_id, task_name=episode.task, num_frames=frames, fps=30,
        camera_resolution=[chest.height, chest.width], data_format="new",
        left_wrist_duplicate_ratio=quality["left"], right_wrist_duplicate_ratio=quality["right"],
        left_wrist_has_issue=quality["left"] > DUPLICATE_ISSUE_RATIO,
        right_wrist_has_issue=quality["right"] > DUPLICATE_ISSUE_RATIO,
    )
    valid = episode.wilor.valid[:frames]
    file["hands"].attrs.update(wilor_available=True, wilor_source_file=WILOR_FILE,
                               wilor_left_valid_frames=int(valid[:, 0].sum()),
                               wilor_right_valid_frames=int(valid[:, 1].sum()))
    attrs = episode.pressure.attrs
    pressure = {"grid_size": 21, "separate_normalization": bool(attrs.get("separate_normalization", False))}
    if pressure["separate_normalization"]:
        pressure.update({key: float(attrs[key]) for key in MAXIMA_KEYS if key in attrs})
    pressure.update({k: bool(v) for k, v in attrs.items() if k.startswith("baseline_corrected_")})
    pressure["normalized"] = grids_normalized(episode.pressure.grids[:frames])
    file["pressure"].attrs.update(pressure)


def _quality(episode: Episode, problems: list[str]) -> dict:
    path = episode.path / QUALITY_FILE
    if not path.exists():
        return {"left": -1.0, "right": -1.0}
    try:
        return read_quality(path)
    except DataError as exc:
        problems.append(str(exc))
        return {"left": -1.0, "right": -1.0}


def source_name(folder: Path, raw_root: Path) -> str:
    """The episode's place under the raw root (`Scene/task/id`): what its trajectory is marked as written from."""
    return Path(os.path.abspath(folder)).relative_to(os.path.abspath(raw_root)).as_posix()


def convert_trajectory(folder: Path, out_path: Path, compression_level: int = 4, source: str = "") -> ConversionResult:
    """Convert one raw folder into `out_path`, marked as written from `source` (default: the folder's name);
    never raises for bad data (the result says what failed)."""
    started = time.perf_counter()
    result = ConversionResult(Path(folder), Path(out_path), "failed")
    missing = [name for name in REQUIRED_FILES if not (Path(folder) / name).exists()]
    if missing:
        result.error = f"{folder}: missing required file(s): {', '.join(missing)}"
        return result
    try:
        with open_raw_episode(folder) as episode:
            result.problems = list(episode.problems)
            unreadable = [name for view, name in VIDEO_FILES.items() if view not in episode.views]
            unreadable += [n for n, s in (("pressure_grids.npz", episode.pressure), ("wilor_hands.json", episode.wilor)) if not s]
            if unreadable or episode.num_frames == 0:
                raise DataError(folder, None, f"cannot convert: unreadable {', '.join(unreadable) or 'frames (0 frames)'}")
            result.quality = _quality(episode, result.problems)
            with hdf5_output(Path(out_path), CONVERTER, source or Path(folder).name) as file:
                decoded = _write_images(file, episode, compression_level)
                frames = min(decoded.values())
                if frames == 0:  # a trajectory of no frame is not one (its readers refuse it)
                    raise DataError(folder, None, "cannot convert: the videos decode no frame")
                if frames < episode.num_frames:
                    result.problems.append(f"{folder}: videos decode only {frames} of {episode.num_frames} frames; cut to {frames}")
                _write_streams(file, episode, frames, compression_level)
                _write_masks(file, episode, frames, compression_level, result.problems)
                _write_attrs(file, episode, frames, result.quality)
        result.status, result.frames = "converted", frames
        result.quality["wilor_valid_ratio"] = _pose_ratio(episode, frames)
        result.damage = damage(episode, decoded, result.problems)
    except Exception as exc:  # noqa: BLE001 - any failure of one trajectory (a library error on damaged
        # bytes included) is that trajectory's result; the batch goes on
        result.error = failure_line(folder, exc)
    result.seconds = time.perf_counter() - started
    return result


def _pose_ratio(episode: Episode, frames: int) -> float:
    """Share of frames with at least one valid WiLoR hand."""
    return float(episode.wilor.valid[:frames].any(axis=1).mean()) if frames else 0.0


def damage(episode: Episode, decoded: dict[str, int], problems: list[str]) -> str | None:
    """What the trajectory converted from `episode` lacks, as one line (None when nothing), parts separated by " | ":
    the frames it holds of the longest video's (`6 of 40 frames (chest.mp4: 9 frames, 6 decode)`; the folder's own
    problems, the frame counts, then go unsaid) and the problems by stream (`episode.problems_in_brief`)."""
    frames, longest = min(decoded.values()), max(source.num_frames for source in episode.views.values())
    parts = []
    if frames < longest:
        parts.append(f"{frames} of {longest} frames ({', '.join(_short_sources(episode, decoded, longest))})")
        problems = [p for p in problems if not p.startswith(f"{episode.path}: ")]
    return " | ".join(parts + problems_in_brief(problems, episode.path)) or None


def _short_sources(episode: Episode, decoded: dict[str, int], longest: int) -> list[str]:
    """The videos (and pressure grids) that end before `longest` frames, each with its count."""
    short = []
    for view, source in episode.views.items():
        if source.num_frames < longest or decoded[view] < episode.num_frames:
            read = f", {decoded[view]} decode" if decoded[view] < episode.num_frames else ""
            short.append(f"{VIDEO_FILES[view]}: {source.num_frames} frames{read}")
    if min(source.num_frames for source in episode.views.values()) > episode.num_frames:
        short.append(f"{GRIDS_FILE}: {episode.num_frames} frames")
    return short
