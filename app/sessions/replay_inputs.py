"""What a replay checks before the model loads (torch takes seconds to import): the episodes it reads — each
opens and has the head camera the model needs — and the comparison video it writes. A bad path is then one
line at once."""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.core.output_safety import check_output
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.comparison_video import is_comparison_video


def require_ego(path: Path, episode: Episode) -> None:
    """UserError when the opened `episode` (from `path`) has no head-camera video."""
    if episode.views.get("ego") is None:
        raise UserError(f"{path}: no ego (chest) video; the model needs it")


def check_episodes(paths: Sequence[Path]) -> None:
    """Each episode opens (raw folder, .hdf5, LeRobot episode or plain video) and has its head camera."""
    for path in paths:
        with open_episode(path) as episode:
            require_ego(path, episode)


def check_video_output(out: Path, inputs: Iterable[Path | None], overwrite: bool) -> None:
    """Before any work: the comparison video `out` is an .mp4 and passes the output rule against the command's
    `inputs` (an earlier comparison video is replaced without `overwrite`)."""
    if out.suffix.lower() != ".mp4":
        raise UserError(f"{out}: the video must be an .mp4 file")
    check_output(out, inputs, overwrite, own=is_comparison_video)
