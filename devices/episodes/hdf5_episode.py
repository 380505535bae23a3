"""HDF5 trajectories in the official EgoTouch schema: dataset names and reading.

Reading is lenient per stream, like raw folders: a missing or malformed dataset becomes a problem line
naming the file and the dataset, and the other streams are still read.
"""
from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from touchanything.core.errors import DataError, describe
from touchanything.core.hand_pose import hands_valid
from touchanything.devices.episodes.episode import Episode, align_note, synthetic_timestamps
from touchanything.devices.episodes.episode_files import PressureFile, range_problem, scalar_attrs
from touchanything.devices.episodes.episode_streams import HandStream, TrackerStream

IMAGE_KEYS = {"ego": "images/chest_color", "wrist_left": "images/left_color", "wrist_right": "images/right_color"}
TRACKER_KEYS = ("poses/chest_pose", "poses/left_pose", "poses/right_pose")
ROKOKO_KEYS = ("hands/left_joint_xyz", "hands/right_joint_xyz")
WILOR_KEYS = ("hands/wilor_left_joint_xyz", "hands/wilor_right_joint_xyz")
WILOR_VALID_KEYS = ("hands/wilor_left_valid", "hands/wilor_right_valid")
GRID_KEYS = ("pressure/left_pressure_grid", "pressure/right_pressure_grid")
MASK_KEYS = ("masks/glove_masks", "masks/glove_obj_ids", "masks/glove_valid_frames")
H5_ERRORS = (OSError, RuntimeError, ValueError, KeyError, TypeError)
"""What h5py raises for a damaged file (a bad checksum or filter, a broken link or header, a foreign type)."""


def _why(exc: Exception) -> str:
    return f"unreadable ({str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__})"


class Hdf5Frames:
    """FrameSource over an `images/*_color` dataset (T, H, W, 3) uint8 RGB. A frame that cannot be read (a
    damaged chunk) is None, like a frame past the end, and the first one is added to `problems`."""

    def __init__(self, file: h5py.File, dataset: h5py.Dataset, problems: list[str] | None = None) -> None:
        self._file, self._dataset = file, dataset
        self.num_frames, self.height, self.width = dataset.shape[:3]
        self._problems = problems if problems is not None else []
        self.unreadable = 0

    def read(self, index: int) -> np.ndarray | None:
        if not 0 <= index < self.num_frames:
            return None
        try:
            return self._dataset[index]
        except H5_ERRORS as exc:
            self.unreadable += 1
            if self.unreadable == 1:
                self._problems.append(describe(self._file.filename, self._dataset.name.lstrip("/"),
                                               f"frame {index}: {_why(exc)}; such frames are shown as missing"))
            return None

    def close(self) -> None:
        if self._file.id.valid:
            self._file.close()


def read_dataset(file: h5py.File, key: str, shape_tail: tuple, kinds: str) -> np.ndarray:
    """Dataset `key` of shape (T, *shape_tail) and a dtype of one of `kinds`; DataError naming it otherwise."""
    try:
        if key not in file:
            raise DataError(file.filename, key, "missing dataset")
        data = file[key]
        if (not isinstance(data, h5py.Dataset) or data.ndim != len(shape_tail) + 1 or data.shape[1:] != shape_tail
                or data.dtype.kind not in kinds):
            raise DataError(file.filename, key, f"has shape {getattr(data, 'shape', None)} and dtype "
                            f"{getattr(data, 'dtype', None)}, expected (T, {', '.join(map(str, shape_tail))}) of kind {kinds!r}")
        return data[()]
    except H5_ERRORS as exc:
        raise DataError(file.filename, key, _why(exc)) from None


def _read(problems: list[str], file: h5py.File, key: str, shape_tail: tuple, kinds: str, optional: bool = False):
    try:
        if optional and key not in file:
            return None
        return read_dataset(file, key, shape_tail, kinds)
    except DataError as exc:
        problems.append(str(exc))
        return None


def _images(problems: list[str], file: h5py.File) -> dict[str, Hdf5Frames]:
    views = {}
    for view, key in IMAGE_KEYS.items():
        try:
            data = file.get(key)
        except H5_ERRORS as exc:
            problems.append(describe(file.filename, key, _why(exc)))
            continue
        if data is None:
            problems.append(describe(file.filename, key, "missing dataset"))
        elif not isinstance(data, h5py.Dataset) or data.ndim != 4 or data.shape[3] != 3 or data.dtype != np.uint8:
            problems.append(describe(file.filename, key, f"has shape {getattr(data, 'shape', None)}, expected (T, H, W, 3) uint8"))
        else:
            views[view] = Hdf5Frames(file, data, problems)
    return views


def _pressure(problems: list[str], file: h5py.File) -> PressureFile | None:
    grids = [_read(problems, file, key, (21, 21), "f") for key in GRID_KEYS]
    if any(g is None for g in grids):
        return None
    if not _same_length(problems, file, dict(zip(GRID_KEYS, grids))):
        return None
    try:
        found = dict(file["pressure"].attrs.items())
    except H5_ERRORS as exc:
        problems.append(describe(file.filename, "pressure", f"attributes {_why(exc)}"))
        found = {}
    attrs, dropped = scalar_attrs(found)
    if dropped:
        problems.append(describe(file.filename, "pressure", f"attribute(s) {', '.join(dropped)} not a number or "
                                 "true/false; ignored"))
    grids = np.stack(grids, axis=1).astype(np.float32)
    if problem := range_problem(grids):
        problems.append(describe(file.filename, "pressure", problem))
    return PressureFile(grids, attrs)


def _same_length(problems: list[str], file: h5py.File, arrays: dict[str, np.ndarray]) -> bool:
    """True when the datasets of one stream hold as many frames each; else a problem naming them."""
    if len({len(a) for a in arrays.values()}) <= 1:
        return True
    problems.append(describe(file.filename, None, "frame counts differ within one stream ("
                             + ", ".join(f"{k} {len(a)}" for k, a in arrays.items()) + "); stream not read"))
    return False


def _optional(file: h5py.File, keys: tuple) -> bool:
    """An optional stream is absent without a problem only when none of its datasets is there."""
    try:
        return not any(key in file for key in keys)
    except H5_ERRORS:
        return False


def _hands(problems: list[str], file: h5py.File, keys: tuple, valid_keys: tuple | None) -> HandStream | None:
    optional = valid_keys is None and _optional(file, keys)
    joints = [_read(problems, file, key, (21, 3), "f", optional=optional) for key in keys]
    if any(j is None for j in joints) or not _same_length(problems, file, dict(zip(keys, joints))):
        return None
    joints = np.stack(joints, axis=1).astype(np.float32)
    valid = hands_valid(joints) & np.any(joints != 0, axis=(-1, -2))
    if valid_keys is not None:
        flags = [_read(problems, file, key, (), "iub") for key in valid_keys]
        if any(f is None for f in flags) or not _same_length(
                problems, file, {"/".join(keys): joints, **dict(zip(valid_keys, flags))}):
            return None
        valid &= np.stack(flags, axis=1).astype(bool)
    joints[~valid] = 0.0
    return HandStream(joints, valid)


def _trackers(problems: list[str], file: h5py.File) -> TrackerStream | None:
    optional = _optional(file, TRACKER_KEYS)
    poses = [_read(problems, file, key, (7,), "f", optional=optional) for key in TRACKER_KEYS]
    if any(p is None for p in poses) or not _same_length(problems, file, dict(zip(TRACKER_KEYS, poses))):
        return None
    poses = np.stack(poses, axis=1).astype(np.float32)
    return TrackerStream(poses, np.all(np.isfinite(poses), axis=-1) & np.any(poses != 0, axis=-1))


def _metadata(problems: list[str], file: h5py.File) -> dict:
    try:
        return dict(file["metadata"].attrs.items()) if "metadata" in file else {}
    except H5_ERRORS as exc:
        problems.append(describe(file.filename, "metadata", f"attributes {_why(exc)}"))
        return {}


def frame_count(file: h5py.File) -> int:
    """The `num_frames` attribute of `metadata`; DataError naming it when it is missing, unreadable (a broken
    link) or not a whole number."""
    try:
        if "metadata" not in file or "num_frames" not in file["metadata"].attrs:
            raise DataError(file.filename, "metadata", "attribute num_frames missing")
        value = file["metadata"].attrs["num_frames"]
    except H5_ERRORS as exc:
        raise DataError(file.filename, "metadata", f"attribute num_frames {_why(exc)}") from None
    array = np.asarray(value)
    if array.ndim != 0 or array.dtype.kind not in "iuf" or not np.isfinite(array) or array != np.round(array) or array < 0:
        raise DataError(file.filename, "metadata", f"attribute num_frames {value!r} is not a whole number ≥ 0")
    return int(array)


def _fps(problems: list[str], path: Path, value) -> float:
    try:
        fps = float(np.asarray(value).item())
    except (TypeError, ValueError):
        fps = float("nan")
    if not (np.isfinite(fps) and 0 < fps <= 1000):
        problems.append(describe(path, "metadata", f"fps {value!r} is not a frame rate; 30 used"))
        return 30.0
    return fps


def open_hdf5_episode(path: Path) -> Episode:
    """Open an official-schema HDF5 trajectory; raises DataError only when the file is not HDF5."""
    path = Path(path)
    if not path.is_file():
        raise DataError(path, None, "file not found")
    try:
        file = h5py.File(path, "r")
    except H5_ERRORS as exc:
        raise DataError(path, None, f"not a readable HDF5 file ({exc})") from None
    problems: list[str] = []
    views = _images(problems, file)
    pressure = _pressure(problems, file)
    wilor = _hands(problems, file, WILOR_KEYS, WILOR_VALID_KEYS)
    rokoko = _hands(problems, file, ROKOKO_KEYS, None)
    trackers = _trackers(problems, file)
    lengths = {IMAGE_KEYS[v]: s.num_frames for v, s in views.items()}
    if pressure is not None:
        lengths["pressure"] = len(pressure.grids)
    others = {name: len(s.valid) for name, s in (("hands/wilor", wilor), ("hands/rokoko", rokoko), ("poses", trackers)) if s}
    frames = min(lengths.values()) if lengths else min(others.values(), default=0)
    if frames == 0:
        file.close()
        empty = [name for name, count in {**lengths, **others}.items() if count == 0]
        raise DataError(path, empty[0] if empty else None, "holds 0 frames; nothing to read"
                        + (f" ({problems[0]})" if problems and not empty else ""))
    if note := align_note({**lengths, **others}, frames):
        problems.append(describe(path, None, note))
    stamps = _read(problems, file, "timestamps", (), "i", optional=True)
    stamps = stamps[:frames].astype(np.int64) if stamps is not None and len(stamps) >= frames else synthetic_timestamps(frames)
    metadata = _metadata(problems, file)
    try:
        frame_count(file)
    except DataError as exc:
        if metadata and "missing" not in exc.problem:  # unread metadata is named above; a missing count is allowed
            problems.append(str(exc))
    task = str(metadata.get("task_name", path.parent.name))
    if pressure is not None:
        pressure.grids = pressure.grids[:frames]
    if not views:
        file.close()
    return Episode(
        path=path, scene=path.parent.parent.name, task=task,
        trajectory_id=str(metadata.get("trajectory_id", path.stem)), num_frames=frames, views=views,
        timestamps_us=stamps, fps=_fps(problems, path, metadata.get("fps", 30)),
        wilor=wilor and wilor.fit(frames), rokoko=rokoko and rokoko.fit(frames),
        trackers=trackers and trackers.fit(frames), pressure=pressure, problems=problems,
    )
