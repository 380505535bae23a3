"""`touchanything info PATH`: summarise an episode folder, an HDF5 trajectory or a dataset root."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.app.sessions.episode_summary import dataset_lines, episode_lines
from touchanything.devices.episodes.episode_loader import episode_exists, open_episode
from touchanything.devices.episodes.raw_episode import is_raw_episode
from touchanything.devices.errors import UserError


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("info", help="summarise an episode, an HDF5 file or a dataset root")
    parser.add_argument("path", type=Path, help="raw episode folder, .hdf5 file, dataset root, LeRobot dataset, or one of "
                                                "its episodes (ROOT/episode_NNNNNN)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    path: Path = args.path
    if not episode_exists(path):
        raise UserError(f"{path}: not found")
    if path.is_dir() and not is_raw_episode(path):
        lines = dataset_lines(path)
    else:
        with open_episode(path) as episode:
            lines = episode_lines(episode)
    print("\n".join(lines))
    return 0
