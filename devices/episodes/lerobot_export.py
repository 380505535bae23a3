"""A dataset root (raw episode folders and HDF5 trajectories) or one episode exported as a LeRobot v3.0 dataset:
checked before any work, written into a temporary folder beside the output and renamed into place when
complete. Each episode's scene, task and trajectory id and its pressure attributes go into the episodes
metadata, so that reading the export back gives the same Episode; a `split.json` of the source becomes one over
the exported episodes (`ROOT/episode_NNNNNN`), so `eval --data OUT` evaluates the export. Damage is said, one line
per episode: each view's frames the source did not decode (written black, 0.0 in `observation.views_valid`) and the
problems found reading it; an episode that cannot be exported (an empty folder among them) is listed as skipped."""
from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError, UserError
from touchanything.core.output_safety import replacing_folder
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes import lerobot_format as fmt
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, read_split
from touchanything.devices.episodes.episode import Episode, problems_in_brief
from touchanything.devices.episodes.episode_loader import find_empty_folders, find_hdf5_files, find_raw_episodes, is_hdf5_path, open_episode
from touchanything.devices.episodes.lerobot_writer import LeRobotWriter


@dataclass
class ExportSummary:
    """episodes / frames written, the views exported, a line per exported episode with damage (`damage_line`),
    sources left out with the reason."""

    episodes: int = 0
    frames: int = 0
    views: tuple[str, ...] = ()
    damaged: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)


def source_episodes(root: Path) -> list[Path]:
    """The raw folders and HDF5 files under `root` (or `root` itself when it is one episode)."""
    root = Path(root)
    if root.is_file():
        return [root] if is_hdf5_path(root) else []
    return find_raw_episodes(root) + find_hdf5_files(root)


def task_text(task: str) -> str:
    """A task id as LeRobot task text: "slide_box_cardboard" → "slide box cardboard"."""
    return task.replace("_", " ").strip() or "unknown task"


def damage_line(path: Path, episode: Episode, filled: dict[str, int]) -> str | None:
    """What is damaged in the exported episode read from `path`, as one line — each view's frames the source did
    not decode (`filled`, written black), then the problems found reading it — or None when nothing is."""
    parts = [f"{view}: {count} of {episode.num_frames} frames do not decode (written black, 0.0 in {fmt.VIEWS_VALID})"
             for view, count in filled.items()]
    parts += problems_in_brief(episode.problems, episode.path)
    return f"{path}: {' | '.join(parts)}" if parts else None


def _source_key(path: Path) -> Path:
    return path.resolve().with_suffix("") if is_hdf5_path(path) else path.resolve()


def _values_outside(episode: Episode, sensor_cells: np.ndarray) -> str | None:
    """Why the episode's pressure cannot be exported without loss (values in cells that are no sensor), else None."""
    if episode.pressure is None:
        return None
    outside = np.isfinite(episode.pressure.grids[:, ~sensor_cells]).any(axis=0)
    if not outside.any():
        return None
    return f"pressure in {int(outside.sum())} grid cells outside the glove layout's {int(sensor_cells.sum())}; they would be lost"


@dataclass
class ExportPlan:
    """The episodes that go together, in order; the views they all have, each (width, height); the frame rate;
    their frames in all."""

    paths: list[Path]
    views: tuple[str, ...]
    sizes: dict[str, tuple[int, int]]
    fps: int
    frames: int


def _plan(sources: list[Path], summary: ExportSummary, sensor_cells: np.ndarray) -> ExportPlan:
    """The episodes that can go together (the views every one has, one size per view, one frame rate, pressure
    only in `sensor_cells`); the others are listed in `summary.skipped`."""
    shape: dict[Path, tuple[dict, float, int]] = {}
    for path in sources:
        try:
            with open_episode(path) as episode:
                if episode.num_frames == 0 or "ego" not in episode.views:
                    why = "no frames" if episode.num_frames == 0 else "no ego (chest) video"
                    summary.skipped.append(" | ".join([f"{path}: {why}", *problems_in_brief(episode.problems, episode.path)]))
                elif (lost := _values_outside(episode, sensor_cells)) is not None:
                    summary.skipped.append(f"{path}: {lost}")
                else:
                    shape[path] = ({v: (s.width, s.height) for v, s in episode.views.items()}, episode.fps, episode.num_frames)
        except DataError as exc:
            summary.skipped.append(str(exc))
    if not shape:
        return ExportPlan([], (), {}, 0, 0)
    first_sizes, first_fps, _ = next(iter(shape.values()))
    views = tuple(v for v in first_sizes if all(v in sizes for sizes, _, _ in shape.values()))
    keep = []
    for path, (sizes, fps, _) in shape.items():
        if fps != first_fps or any(sizes[v] != first_sizes[v] for v in views):
            summary.skipped.append(f"{path}: {fps:g} fps / sizes {sizes} differ from the first episode's "
                                   f"({first_fps:g} fps, {first_sizes}); a dataset has one of each")
        else:
            keep.append(path)
    return ExportPlan(keep, views, {v: first_sizes[v] for v in views}, round(first_fps), sum(shape[p][2] for p in keep))


def _extra(episode: Episode, source: str) -> dict[str, str]:
    attrs = episode.pressure.attrs if episode.pressure is not None else {}
    return {"scene": episode.scene, "task_name": episode.task, "trajectory_id": episode.trajectory_id,
            "source": source, "pressure_attrs": json.dumps(attrs)}


def source_name(root: Path, path: Path) -> str:
    """Where an exported episode came from, relative to the exported ROOT ("Home/press_button/001"; the episode's
    own name when ROOT is that episode): no local absolute path goes into a dataset that may be published."""
    relative = Path(os.path.relpath(path, root))
    return path.name if relative == Path(".") else relative.as_posix()


def _source_split(root: Path) -> dict[str, list[Path]] | None:
    """The split.json of ROOT (of its folder when ROOT is one file), None when there is none."""
    split_path = (root if root.is_dir() else root.parent) / SPLIT_FILE
    return read_split(split_path) if split_path.is_file() else None


def in_split_order(paths: list[Path], split: dict[str, list[Path]] | None) -> tuple[list[Path], dict[str, str]]:
    """`paths` ordered by the split's lists (train, val, test_seen, test_unseen; episodes no list names last, in
    their order) and LeRobot's `splits`: each non-empty list's episode range "first:end". Without a split, every
    episode is "train", as LeRobot writes it."""
    if split is None:
        return paths, {"train": f"0:{len(paths)}"}
    listed = {_source_key(p): key for key in SPLIT_KEYS for p in split[key]}
    ordered, ranges = [], {}
    for key in SPLIT_KEYS:
        members = [path for path in paths if listed.get(_source_key(path)) == key]
        if members:
            ranges[key] = f"{len(ordered)}:{len(ordered) + len(members)}"
            ordered += members
    return ordered + [path for path in paths if _source_key(path) not in listed], ranges


def _write_split(split: dict[str, list[Path]] | None, folder: Path, written: list[Path]) -> None:
    """The source's split.json over the exported episodes (entries not exported are left out)."""
    if split is None:
        return
    index = {_source_key(path): k for k, path in enumerate(written)}
    out = {key: [fmt.episode_address(Path("."), index[_source_key(p)]).name for p in split[key] if _source_key(p) in index]
           for key in SPLIT_KEYS}
    (folder / SPLIT_FILE).write_text(json.dumps(out, indent=1) + "\n")


def check_action(action: str | None) -> None:
    """A UserError unless `action` is None or a feature `--action` can name."""
    if action is not None and action not in fmt.ACTION_CHOICES:
        raise UserError(f"--action {action}: not an exported feature that can be the action "
                        f"(choose one of {', '.join(fmt.ACTION_CHOICES)})")


def export_lerobot(root: Path, out: Path, overwrite: bool = False, action: str | None = None,
                   on_frames: Callable[[int, int], None] = lambda written, total: None) -> ExportSummary:
    """Export every episode under `root` into the LeRobot dataset `out`, feature `action` (if any) as LeRobot's
    `action`; `on_frames(written, total)` after each episode frame written (every view's picture of it)."""
    check_action(action)
    root, out = Path(root), Path(out)
    sensor_cells = TactileLayout.default().valid
    sources = source_episodes(root)
    if not sources:
        raise UserError(f"{root}: no episodes found (raw folders with chest.mp4, or .hdf5 files)")
    summary = ExportSummary()
    plan = _plan(sources, summary, sensor_cells)
    if not plan.paths:
        raise UserError(f"{root}: none of the {len(sources)} episodes can be exported ({summary.skipped[0]})")
    summary.skipped += [f"{folder}: an empty folder (no episode files)" for folder in find_empty_folders(root)]
    summary.views = plan.views
    split = _source_split(root)
    paths, splits = in_split_order(plan.paths, split)
    written = 0

    def frame_written() -> None:
        nonlocal written
        written += 1
        on_frames(written, plan.frames)

    with replacing_folder(out, overwrite) as partial:
        writer = LeRobotWriter(partial, plan.fps, plan.views, plan.sizes, splits, sensor_cells, action, frame_written)
        for path in paths:
            with open_episode(path) as episode:
                filled = writer.add(episode, task_text(episode.task), _extra(episode, source_name(root, path)))
                if (line := damage_line(path, episode, filled)) is not None:
                    summary.damaged.append(line)
            summary.episodes, summary.frames = summary.episodes + 1, summary.frames + episode.num_frames
        writer.close()
        _write_split(split, partial, paths)
    return summary
