"""LeRobot datasets read back as Episodes: `open_lerobot_episode(root, index)` for `ROOT/episode_NNNNNN`
(`devices.episodes.lerobot_format`), codebase v3.0 (this project's export and others) and the older
one-file-per-episode layout of v2.x, as the community EgoTouch conversion has it.

This project's export (`lerobot_format.FEATURE_INFO`) is read by its features' names: the joints and seen flags
from `observation.state`, the maps from the cells `observation.tactile`'s values are named by (NaN elsewhere and
for hands `observation.tactile_valid` says were not measured), the trackers from `observation.trackers`; a
feature exported as `action` says so (`info.exported_from`); a picture `observation.views_valid` marks as standing
in for one the source did not decode reads as missing (None), and the episode's problems count them. Other
datasets and older exports are read by name and shape: video features by their last name part (`VIEW_ALIASES`),
the tactile maps as the float feature of shape (2, 21, 21), the joints (2, 21, 3), the trackers (3, 7). The hand
order is taken from the feature's `names` (`{"hand": [...]}` or a list naming left and right); where no order is stated, a
dataset laid out like the community EgoTouch conversion (v2.x, head camera `observation.images.main`) is
[right, left] as that conversion documents, anything else is taken as the official [left, right] and the episode
says so in its problems. Everything is returned in the official order [left, right].
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from touchanything.core.errors import DataError, describe
from touchanything.core.hand_pose import hands_valid
from touchanything.core.json_files import read_json_file
from touchanything.core.snapshot import HANDS
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_files import PressureFile, scalar_attrs
from touchanything.devices.episodes.episode_streams import HandStream, TrackerStream
from touchanything.devices.episodes.video_io import VideoReader


class LeRobotFrames:
    """FrameSource over frames `first`… of a video file that holds several episodes one after the other. `recorded`:
    (num_frames,) bool, False where the export wrote a black picture in place of one its source did not decode
    (read as missing, None), or None when every frame is taken as recorded."""

    def __init__(self, reader: VideoReader, first: int, num_frames: int, recorded: np.ndarray | None = None) -> None:
        self.reader, self.first, self.num_frames, self.recorded = reader, first, num_frames, recorded
        self.width, self.height = reader.width, reader.height

    def read(self, index: int) -> np.ndarray | None:
        if not 0 <= index < self.num_frames or (self.recorded is not None and not self.recorded[index]):
            return None
        return self.reader.read(self.first + index)

    def close(self) -> None:
        self.reader.close()


def read_info(root: Path) -> dict:
    """`meta/info.json`, checked for what the reader needs (fps, features)."""
    info = read_json_file(Path(root) / fmt.INFO_PATH)
    if not isinstance(info, dict) or not isinstance(info.get("features"), dict):
        raise DataError(Path(root) / fmt.INFO_PATH, None, "not a LeRobot info.json (no features)")
    try:
        if not 0 < float(info["fps"]) <= 1000:
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise DataError(Path(root) / fmt.INFO_PATH, "fps", f"{info.get('fps')!r} is not a frame rate") from None
    return info


def _is_v3(info: dict) -> bool:
    return str(info.get("codebase_version", "")).startswith("v3")


def episode_rows(root: Path, info: dict) -> dict[int, dict]:
    """{episode index: its row of the episodes metadata} (v3: the parquet files without their statistics
    columns; v2.x: `meta/episodes.jsonl`)."""
    root = Path(root)
    if _is_v3(info):
        rows = {}
        for path in sorted((root / fmt.EPISODES_DIR).glob("*/*.parquet")):
            try:
                schema = pq.read_schema(path)
                table = pq.read_table(path, columns=[n for n in schema.names if not n.startswith("stats/")])
            except (OSError, pa.ArrowException) as exc:
                raise DataError(path, None, f"not a readable parquet file ({exc})") from None
            rows.update({int(row["episode_index"]): row for row in table.to_pylist()})
        return rows
    path = root / "meta" / "episodes.jsonl"
    try:
        lines = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    except FileNotFoundError:
        return {index: {"episode_index": index} for index in range(int(info.get("total_episodes", 0)))}
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(path, None, f"not readable JSON lines ({exc})") from None
    return {int(row["episode_index"]): row for row in lines if isinstance(row, dict) and "episode_index" in row}


def find_lerobot_episodes(root: Path) -> list[Path]:
    """The addresses `ROOT/episode_NNNNNN` of every episode of the dataset at `root` (none when it is not one)."""
    if not fmt.is_lerobot_root(root):
        return []
    return [fmt.episode_address(root, index) for index in sorted(episode_rows(root, read_info(root)))]


def _data_table(root: Path, info: dict, row: dict, index: int) -> pa.Table:
    """The frame rows of episode `index`, in frame order."""
    if _is_v3(info):
        path = root / info["data_path"].format(chunk_index=row["data/chunk_index"], file_index=row["data/file_index"])
    else:
        path = root / info["data_path"].format(episode_chunk=index // int(info.get("chunks_size", fmt.CHUNKS_SIZE)),
                                               episode_index=index)
    try:
        table = pq.read_table(path)
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except (OSError, pa.ArrowException) as exc:
        raise DataError(path, None, f"not a readable parquet file ({exc})") from None
    if "episode_index" in table.column_names:
        table = table.filter(pc.equal(table["episode_index"], index))
    return table.sort_by("frame_index") if "frame_index" in table.column_names else table


def _array(table: pa.Table, name: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """Column `name` as a (frames, *shape) array (nested or flat lists), or None when its size differs."""
    column = table[name].combine_chunks()
    while pa.types.is_list(column.type) or pa.types.is_fixed_size_list(column.type) or pa.types.is_large_list(column.type):
        column = column.flatten()
    values = column.to_numpy(zero_copy_only=False)
    if values.size != table.num_rows * int(np.prod(shape)):
        return None
    return values.reshape((table.num_rows, *shape)) if shape != (1,) else values


def _feature(info: dict, table: pa.Table, shape: tuple[int, ...], preferred: str) -> tuple[str, np.ndarray] | None:
    """The (name, values) of the float feature `preferred`, else of the first float feature of `shape`."""
    features = info["features"]
    names = [preferred] + [n for n, f in features.items() if n != preferred]
    for name in names:
        feature = features.get(name)
        if (isinstance(feature, dict) and name in table.column_names and tuple(feature.get("shape", ())) == shape
                and str(feature.get("dtype", "")).startswith("float")):
            values = _array(table, name, shape)
            if values is not None:
                return name, values.astype(np.float32)
    return None


def _exported(info: dict, table: pa.Table, name: str) -> tuple[str, dict] | None:
    """(key, feature) of this project's 1-D feature `name` (under its own name, or `action` when exported as it)."""
    for key, feature in info["features"].items():
        if not isinstance(feature, dict) or key not in table.column_names:
            continue
        extra = feature.get("info") if isinstance(feature.get("info"), dict) else {}
        shape = feature.get("shape")
        if ((key == name and extra.get("exported_from", name) == name) or extra.get("exported_from") == name) and \
                isinstance(shape, list) and len(shape) == 1 and str(feature.get("dtype", "")).startswith("float"):
            return key, feature
    return None


def _named(root: Path, info: dict, table: pa.Table, name: str, names: list[str]) -> np.ndarray | None:
    """The (frames, len(names)) values of this project's feature `name` (None when there is none, or when it is
    another dataset's feature of that name); DataError when an export of ours names its values otherwise."""
    found = _exported(info, table, name)
    if found is None:
        return None
    key, feature = found
    values = _array(table, key, (len(names),)) if feature.get("names") == names else None
    if values is None and isinstance(feature.get("info"), dict) and fmt.FEATURE_INFO[name].keys() <= feature["info"].keys():
        raise DataError(root / fmt.INFO_PATH, f"{key} names", f"not the {len(names)} names this project exports "
                                                              f"({names[0]} … {names[-1]})")
    return values


def _hand_state(root: Path, info: dict, table: pa.Table) -> HandStream | None:
    """The joints and seen flags of `observation.state` when it is this project's (named as `STATE_NAMES`)."""
    if (state := _named(root, info, table, fmt.STATE, fmt.STATE_NAMES)) is None:
        return None
    joints = state[:, :fmt.JOINT_VALUES].reshape(-1, 2, 21, 3).astype(np.float32)
    seen = state[:, fmt.JOINT_VALUES:] > 0.5
    return HandStream(np.where(seen[..., None, None], joints, 0.0).astype(np.float32), seen)


def _tactile_cells(root: Path, info: dict, table: pa.Table) -> np.ndarray | None:
    """(frames, 2, 21, 21) maps from this project's `observation.tactile` (values named by cell): NaN in cells
    without a value and for hands `observation.tactile_valid` says were not measured."""
    found = _exported(info, table, fmt.TACTILE)
    if found is None:
        return None
    key, feature = found
    cells = fmt.cells_of(feature.get("names"))
    values = _array(table, key, (len(cells[0]),)) if cells is not None else None
    if values is None:
        raise DataError(root / fmt.INFO_PATH, f"{key} names", "not one grid cell name (left.r02c05 …) per value")
    grids = np.full((table.num_rows, 2, 21, 21), np.nan, np.float32)
    grids[:, cells[0], cells[1], cells[2]] = values
    measured = _flags(table, fmt.TACTILE_VALID, 2)
    if measured is not None:
        grids[~measured] = np.nan
    return grids


def hand_order(info: dict, name: str) -> tuple[list[str], bool]:
    """(hand order of feature `name`, whether the dataset states it)."""
    names = info["features"][name].get("names")
    stated = names.get("hand") or names.get("hands") if isinstance(names, dict) else names
    if isinstance(stated, list) and sorted(map(str, stated)) == ["left", "right"]:
        return [str(h) for h in stated], True
    community = not _is_v3(info) and "observation.images.main" in info["features"]
    return (["right", "left"] if community else list(HANDS)), False


def _official_order(info: dict, name: str, problems: list[str], root: Path) -> bool:
    """Whether feature `name`'s hands must be swapped into the official order [left, right]."""
    order, stated = hand_order(info, name)
    if not stated:
        problems.append(describe(root / fmt.INFO_PATH, name, f"no hand order in its names; read as [{', '.join(order)}]"))
    return order == ["right", "left"]


def _flags(table: pa.Table, name: str, count: int) -> np.ndarray | None:
    if name not in table.column_names:
        return None
    values = _array(table, name, (count,))
    return None if values is None else values.astype(bool)  # bool, or float 0 / 1


def _recorded(root: Path, info: dict, table: pa.Table, index: int, problems: list[str]) -> dict[str, np.ndarray]:
    """{video feature name's last part: (frames,) bool} from this project's `observation.views_valid` (none when the
    dataset has none); a line in `problems` for each view with frames the export filled."""
    feature = info["features"].get(fmt.VIEWS_VALID)
    names = feature.get("names") if isinstance(feature, dict) else None
    if not isinstance(names, list) or fmt.VIEWS_VALID not in table.column_names:
        return {}
    values = _flags(table, fmt.VIEWS_VALID, len(names))
    if values is None:
        raise DataError(root / fmt.INFO_PATH, f"{fmt.VIEWS_VALID} names", f"{len(names)} names for another number of values")
    for name, recorded in zip(names, values.T):
        if not recorded.all():
            problems.append(describe(fmt.episode_address(root, index), fmt.VIEWS_VALID, f"{name}: {int((~recorded).sum())} "
                                     f"of {len(recorded)} frames did not decode in the source (black in the video); "
                                     "read as missing"))
    return dict(zip(map(str, names), values.T))


def _views(root: Path, info: dict, row: dict, index: int, frames: int, problems: list[str],
           recorded: dict[str, np.ndarray]) -> dict[str, LeRobotFrames]:
    views = {}
    for key, feature in info["features"].items():
        if not isinstance(feature, dict) or feature.get("dtype") != "video":
            continue
        view = fmt.VIEW_ALIASES.get(key.rsplit(".", 1)[-1])
        if view is None or view in views:
            problems.append(describe(root / fmt.INFO_PATH, key, "video feature not read (not a head or wrist camera)"))
            continue
        if _is_v3(info):
            path = root / info["video_path"].format(video_key=key, chunk_index=row[f"videos/{key}/chunk_index"],
                                                    file_index=row[f"videos/{key}/file_index"])
            first = round(float(row[f"videos/{key}/from_timestamp"]) * float(info["fps"]))
        else:
            chunk = index // int(info.get("chunks_size", fmt.CHUNKS_SIZE))
            path, first = root / info["video_path"].format(episode_chunk=chunk, video_key=key, episode_index=index), 0
        try:
            reader = VideoReader(path)
        except DataError as exc:
            problems.append(str(exc))
            continue
        if reader.num_frames < first + frames:
            problems.append(describe(path, None, f"holds {reader.num_frames} frames, the episode needs {first + frames}; "
                                                 "the missing ones are shown as missing"))
        views[view] = LeRobotFrames(reader, first, frames, recorded.get(key.rsplit(".", 1)[-1]))
    return views


def open_lerobot_episode(root: Path, index: int) -> Episode:
    """Episode `index` of the LeRobot dataset at `root`; DataError when it is not there or its data unreadable."""
    root = Path(root)
    info = read_info(root)
    rows = episode_rows(root, info)
    if index not in rows:
        raise DataError(fmt.episode_address(root, index), None, f"no such episode (the dataset has {len(rows)}: "
                        f"episode_000000 … episode_{max(len(rows) - 1, 0):06d})")
    row, problems = rows[index], []
    table = _data_table(root, info, row, index)
    frames, fps = table.num_rows, float(info["fps"])
    stamps = next((_array(table, name, (1,)) for name in (fmt.CAPTURE_TIME, fmt.OLD_CAPTURE_TIME) if name in table.column_names), None)
    if stamps is None:
        seconds = _array(table, "timestamp", (1,)) if "timestamp" in table.column_names else np.arange(frames) / fps
        stamps = np.round(np.asarray(seconds, np.float64) * 1e6)
    wilor, pressure, trackers = _hand_state(root, info, table), None, None
    if wilor is None and (found := _feature(info, table, (2, 21, 3), fmt.JOINTS)) is not None:
        swap = _official_order(info, found[0], problems, root)
        joints, valid = found[1], _flags(table, fmt.JOINTS_VALID, 2)
        valid = hands_valid(joints) & np.any(joints != 0, axis=(-1, -2)) if valid is None else valid
        joints, valid = (joints[:, ::-1], valid[:, ::-1]) if swap else (joints, valid)
        wilor = HandStream(np.where(valid[..., None, None], joints, 0.0).astype(np.float32), valid.copy())
    attrs, _ = scalar_attrs(json.loads(row.get("pressure_attrs") or "{}"))
    if (grids := _tactile_cells(root, info, table)) is not None:
        pressure = PressureFile(grids, attrs)
    elif (found := _feature(info, table, (2, 21, 21), fmt.TACTILE)) is not None:
        grids = found[1][:, ::-1] if _official_order(info, found[0], problems, root) else found[1]
        pressure = PressureFile(np.ascontiguousarray(grids), attrs)
    poses = _named(root, info, table, fmt.TRACKERS, fmt.TRACKER_NAMES)
    if poses is None and (found := _feature(info, table, (3, 7), fmt.TRACKERS)) is not None:
        poses = found[1]
    if poses is not None:
        poses, valid = poses.reshape(-1, 3, 7).astype(np.float32), _flags(table, fmt.TRACKERS_VALID, 3)
        trackers = TrackerStream(poses, np.any(poses != 0, axis=-1) if valid is None else valid)
    tasks = row.get("tasks") or []
    return Episode(
        path=fmt.episode_address(root, index), scene=str(row.get("scene") or ""),
        task=str(row.get("task_name") or (tasks[0] if tasks else "")),
        trajectory_id=str(row.get("trajectory_id") or f"episode_{index:06d}"), num_frames=frames,
        views=_views(root, info, row, index, frames, problems, _recorded(root, info, table, index, problems)),
        timestamps_us=np.asarray(stamps, np.int64),
        wilor=wilor, trackers=trackers, pressure=pressure, problems=problems, fps=fps)
