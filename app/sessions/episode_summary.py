"""Text summaries of an episode (streams, pose, glove, pressure, problems) and of a dataset root, printed by
`touchanything info` and before a replay."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from touchanything.core.errors import DataError, UserError, failure_line
from touchanything.core.snapshot import HANDS, TRACKER_ROLES, VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import VIEW_LABELS, view_set_name
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, read_split
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import (
    episode_exists,
    find_hdf5_files,
    find_raw_episodes,
    is_plain_video,
    open_episode,
)
from touchanything.devices.episodes.episode_verify import verify_episode
from touchanything.devices.episodes.lerobot_checks import metadata_problems
from touchanything.devices.episodes.lerobot_episode import find_lerobot_episodes
from touchanything.devices.episodes.raw_episode import is_raw_episode
from touchanything.inference.evaluation.metrics import contact_frames

ROOT_PROBLEMS_SHOWN = 3
"""Problems listed per trajectory in a dataset root's summary (the rest are counted)."""


def _percent(values: np.ndarray) -> str:
    return f"{100.0 * float(np.mean(values)):.0f}%" if values.size else "n/a"


def _pressure_lines(episode: Episode) -> list[str]:
    """Per-hand pressure statistics and the official contact share (both hands pooled)."""
    if episode.pressure is None:
        return ["pressure  none"]
    grids = episode.pressure.grids
    lines = []
    for h, hand in enumerate(HANDS):
        cells = grids[:, h][~np.isnan(grids[:, h])]
        finite = np.isfinite(cells)
        if not finite.all():
            lines.append(f"pressure  {hand}: {int((~finite).sum())} inf values")
        cells = cells[finite]
        stats = f"mean {cells.mean():.3f}, max {cells.max():.3f}" if cells.size else "no valid cells"
        lines.append(f"pressure  {hand}: {stats}")
    contact = contact_frames(grids, TactileLayout.default().bend)
    attrs = episode.pressure.attrs
    norm = "separate (tactile/bend maxima stored)" if attrs.get("separate_normalization") else "not recorded"
    lines.append(f"contact   {_percent(contact)} of frames (official rule: ≥ 5% of tactile cells > 0.1)")
    lines.append(f"normalisation {norm}; baseline corrected: "
                 + ", ".join(f"{h} {attrs.get(f'baseline_corrected_{h}', 'unknown')}" for h in HANDS))
    return lines


def episode_lines(episode: Episode) -> list[str]:
    """Streams, pose and glove coverage, pressure statistics and the problems of one episode."""
    seconds = episode.num_frames / episode.fps if episode.fps else 0.0
    name = "plain video" if is_plain_video(episode) else f"{episode.scene}/{episode.task}/{episode.trajectory_id}"
    lines = [f"episode   {name}  ({episode.path})",
             f"frames    {episode.num_frames} at {episode.fps:g} fps ({seconds:.1f} s)"]
    lines.append("views     " + _views_text(episode))
    for name in ("wilor", "rokoko"):
        hands = episode.hands(name)
        if hands is not None:
            lines.append(f"pose      {name}: " + ", ".join(f"{h} valid {_percent(hands.valid[:, i])}" for i, h in enumerate(HANDS)))
    if episode.glove is not None:
        lines.append("glove     raw present " + ", ".join(f"{h} {_percent(episode.glove.present[:, i])}" for i, h in enumerate(HANDS)))
    if episode.trackers is not None:
        lines.append("trackers  " + ", ".join(f"{r} {_percent(episode.trackers.valid[:, i])}" for i, r in enumerate(TRACKER_ROLES)))
    lines += _pressure_lines(episode)
    lines.append(f"problems  {len(episode.problems) or 'none'}")
    return lines + _problem_lines(episode.problems, "  ")


def _views_text(episode: Episode) -> str:
    """"ego+left: head camera 640×480 (300 frames); left wrist camera 640×480 (300 frames)": the view set's id
    (what `--views` takes), then each view by its label."""
    views = {v: episode.views[v] for v in VIEW_NAMES if v in episode.views}
    if not views:
        return "none"
    sizes = [f"{VIEW_LABELS[v]} {source.width}×{source.height} ({source.num_frames} frames)" for v, source in views.items()]
    return f"{view_set_name(tuple(views))}: " + "; ".join(sizes)


def _problem_lines(problems: list[str], indent: str, limit: int | None = None) -> list[str]:
    """One `- problem` line each; with a `limit`, the first `limit` and then "… and N more"."""
    shown = problems[:limit]
    more = [f"{indent}… and {len(problems) - len(shown)} more"] if len(problems) > len(shown) else []
    return [f"{indent}- {p}" for p in shown] + more


def verify_lines(path: Path, indent: str = "") -> list[str]:
    """`info --verify`: every chunk and frame of the episode read; one line saying so, then the damage."""
    damage = verify_episode(path)
    head = f"{indent}verified  every chunk and video frame read: " + (f"{len(damage)} damaged part(s)" if damage else "no damage")
    return [head] + _problem_lines(damage, indent + "  ")


NOT_VERIFIED = "verified  no: video frames and image chunks were not read (info --verify reads and decodes every one)"


def dataset_lines(root: Path, verify: bool = False) -> tuple[list[str], int]:
    """One line per trajectory under a dataset root (its first problems), the total and the split; with
    `verify`, each trajectory read in full (`verify_lines`). Returns the lines and the number of trajectories
    that could not be read or (verified) hold damage; any failure of one trajectory is named, the rest read."""
    raw, hdf5, lerobot = find_raw_episodes(root), find_hdf5_files(root), find_lerobot_episodes(root)
    if not raw and not hdf5 and not lerobot:
        raise UserError(f"{root}: no episodes found (raw folders with chest.mp4, .hdf5 files, or a LeRobot dataset)")
    found = f"{len(raw)} raw episode(s), {len(hdf5)} HDF5 file(s)" + (f", {len(lerobot)} LeRobot episode(s)" if lerobot else "")
    lines, total, failed = [f"dataset   {root}: {found}"], 0, 0
    for path in raw + hdf5 + lerobot:
        name = os.path.relpath(path, root)
        try:
            with open_episode(path) as ep:
                total += ep.num_frames
                pose = (f"left {_percent(ep.wilor.valid[:, 0])}, right {_percent(ep.wilor.valid[:, 1])}"
                        if ep.wilor is not None else "none")
                contact = _percent(contact_frames(ep.pressure.grids, TactileLayout.default().bend)) if ep.pressure else "n/a"
                lines.append(f"  {name}: {ep.num_frames} frames, views {view_set_name(ep.view_names) or 'none'}, "
                             f"wilor poses {pose}, contact {contact}, problems {len(ep.problems)}")
                problems = [p.removeprefix(f"{root}{os.sep}") for p in ep.problems]
                lines += _problem_lines(problems, "      ", ROOT_PROBLEMS_SHOWN)
        except Exception as exc:  # noqa: BLE001 - one trajectory that cannot be read never stops the others
            lines.append(f"  {name}: unreadable: {failure_line(path, exc)}")
            failed += 1
            continue
        if verify:
            damage = verify_lines(path, "      ")
            failed += len(damage) > 1
            lines += damage
    lines.append(f"total     {total} frames ({total / 30 / 60:.1f} min at 30 fps)"
                 + (f"; {failed} trajector{'y' if failed == 1 else 'ies'} unreadable or damaged" if failed else ""))
    if lerobot and not failed:
        lines += [f"problem   {line}" for line in metadata_problems(root, len(lerobot), total)]
    split_path = root / SPLIT_FILE
    if split_path.exists():
        try:
            lines.append(_split_line(read_split(split_path)))
        except DataError as exc:
            lines.append(f"split     unreadable: {exc}")
    if not verify:
        lines.append(NOT_VERIFIED)
    return lines, failed


def _split_line(split: dict[str, list[Path]]) -> str:
    """The split's counts; a listed `<id>.hdf5` beside the raw folder `<id>/` it will be converted from (a
    simulated or raw root's split names the files `convert` writes) is "to convert", not missing."""
    absent = [p for key in SPLIT_KEYS for p in split[key] if not episode_exists(p)]
    to_convert = sum(p.suffix == ".hdf5" and is_raw_episode(p.with_suffix("")) for p in absent)
    notes = [f"{to_convert} listed HDF5 file(s) to be written by `touchanything convert`" if to_convert else "",
             f"{len(absent) - to_convert} listed file(s) missing" if len(absent) > to_convert else ""]
    return "split     " + ", ".join(f"{k} {len(split[k])}" for k in SPLIT_KEYS) + "".join(f"; {n}" for n in notes if n)
