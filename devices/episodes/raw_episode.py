"""Raw EgoTouch episode folders `<root>/<Scene>/<task>/<trajectory_id>/`: file names and reading.

Every stream is read on its own: a missing or broken file becomes a problem line and that stream is
absent, the others are still read. The frame count is that of the shortest video / pressure-grid stream;
JSON streams are cut or padded (invalid) to it, and every mismatch is reported.
"""
from __future__ import annotations

from pathlib import Path

from touchanything.core.errors import DataError, describe
from touchanything.core.temporary_files import recorded_stream
from touchanything.devices.episodes.episode import Episode, align_note, synthetic_timestamps
from touchanything.devices.episodes.episode_files import read_pressure_grids
from touchanything.devices.episodes.episode_streams import read_glove, read_hands, read_trackers
from touchanything.devices.episodes.video_io import VideoReader

VIDEO_FILES = {"ego": "chest.mp4", "wrist_left": "left.mp4", "wrist_right": "right.mp4"}
WILOR_FILE = "wilor_hands.json"
ROKOKO_FILE = "rokoko_hands.json"
VIVE_FILE = "vive_poses.json"
GLOVE_FILE = "jq_pressure.json"
GRIDS_FILE = "pressure_grids.npz"
MASKS_FILE = "masks.npz"
CAMERA_FILE = "camera_matrix.txt"
QUALITY_FILE = "quality_issues.json"
REQUIRED_FILES = (*VIDEO_FILES.values(), GRIDS_FILE, WILOR_FILE, GLOVE_FILE)


def episode_file(folder: Path, name: str) -> Path:
    """Where the episode's file `name` is: `folder/name`, or, for a recording cut short before it renamed its
    streams into place, the stream's marked temporary file (`temporary_files.recorded_stream`)."""
    path = Path(folder) / name
    return path if path.exists() else recorded_stream(folder, name) or path


def is_raw_episode(folder: Path) -> bool:
    """The official discovery test: a folder holding `chest.mp4` (or, for recordings, `jq_pressure.json`; a
    recording cut short holds them under their temporary names)."""
    return episode_file(folder, VIDEO_FILES["ego"]).is_file() or episode_file(folder, GLOVE_FILE).is_file()


def missing_note(folder: Path, name: str) -> str:
    """Why a required file may be missing, and the fix: a recording cut short has no pressure grids yet."""
    if name == GRIDS_FILE and episode_file(folder, GLOVE_FILE).is_file():
        return (f"missing required file (a recording cut short?); compute it from {GLOVE_FILE} with "
                f"`touchanything grids {folder}`")
    return "missing required file"


def _try(problems: list[str], read, *args):
    try:
        return read(*args)
    except DataError as exc:
        problems.append(str(exc))
        return None


def _stream(problems: list[str], folder: Path, name: str, read):
    path = episode_file(folder, name)
    if not path.exists():
        return None
    result = _try(problems, read, path)
    if result is None:
        return None
    value, stream_problems = result
    problems.extend(stream_problems)
    return value


def open_raw_episode(folder: Path) -> Episode:
    """Open a raw episode folder; raises DataError only when the folder itself is unusable.

    Timestamps are the official synthetic ones (i · 33333 µs); the glove's host times stay in `glove`.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(folder, None, "not a folder" if folder.exists() else "folder not found")
    files = {name: episode_file(folder, name) for name in (*REQUIRED_FILES, ROKOKO_FILE, VIVE_FILE)}
    problems = [describe(folder / n, None, missing_note(folder, n))
                for n in REQUIRED_FILES if not files[n].exists()]
    problems += [describe(folder / n, None, f"read from {path.name}: a recording cut short before it named its files")
                 for n, path in files.items() if path.name != n]
    views = {}
    for view, name in VIDEO_FILES.items():
        if files[name].exists() and (reader := _try(problems, VideoReader, files[name])) is not None:
            views[view] = reader
    pressure = _try(problems, read_pressure_grids, folder / GRIDS_FILE) if (folder / GRIDS_FILE).exists() else None
    if pressure is not None:
        problems.extend(pressure.problems)
    wilor = _stream(problems, folder, WILOR_FILE, read_hands)
    rokoko = _stream(problems, folder, ROKOKO_FILE, read_hands)
    trackers = _stream(problems, folder, VIVE_FILE, read_trackers)
    glove = _stream(problems, folder, GLOVE_FILE, read_glove)

    lengths = {VIDEO_FILES[v]: r.num_frames for v, r in views.items()}
    if pressure is not None:
        lengths[GRIDS_FILE] = pressure.grids.shape[0]
    optional = {WILOR_FILE: wilor and wilor.valid, ROKOKO_FILE: rokoko and rokoko.valid,
                VIVE_FILE: trackers and trackers.valid, GLOVE_FILE: glove and glove.present}
    others = {name: len(a) for name, a in optional.items() if a is not None}
    frames = min(lengths.values()) if lengths else min(others.values(), default=0)
    if note := align_note({**lengths, **others}, frames):
        problems.append(describe(folder, None, note))
    if pressure is not None:
        pressure.grids = pressure.grids[:frames]
    return Episode(
        path=folder, scene=folder.parent.parent.name, task=folder.parent.name, trajectory_id=folder.name,
        num_frames=frames, views=views, timestamps_us=synthetic_timestamps(frames),
        wilor=wilor and wilor.fit(frames), rokoko=rokoko and rokoko.fit(frames),
        trackers=trackers and trackers.fit(frames), pressure=pressure, glove=glove and glove.fit(frames),
        problems=problems,
    )
