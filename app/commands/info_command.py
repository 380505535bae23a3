"""`touchanything info PATH`: summarise an episode folder, an HDF5 trajectory or a dataset root."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.core.errors import UserError, failure_line


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("info", help="summarise an episode, an HDF5 file or a dataset root")
    parser.add_argument("path", type=Path, help="raw episode folder, .hdf5 file, dataset root, LeRobot dataset, or one of "
                                                "its episodes (ROOT/episode_NNNNNN)")
    parser.add_argument("--verify", action="store_true", help="read every chunk of every dataset and decode every video "
                        "frame, and report what is damaged (exit status 1 when something is)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.episode_summary import NOT_VERIFIED, dataset_lines, episode_lines, verify_lines
    from touchanything.devices.episodes.episode_loader import episode_exists, open_episode
    from touchanything.devices.episodes.raw_episode import is_raw_episode

    """Exit status 1 when a trajectory of a root cannot be read, or (with --verify) something is damaged."""
    path: Path = args.path
    if not episode_exists(path):
        raise UserError(f"{path}: not found")
    if path.is_dir() and not is_raw_episode(path):
        lines, failed = dataset_lines(path, args.verify)
    else:
        try:
            with open_episode(path) as episode:
                lines = episode_lines(episode)
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - damaged bytes can make a library raise anything: one line
            raise UserError(failure_line(path, exc)) from None
        verified = verify_lines(path) if args.verify else [NOT_VERIFIED]
        lines, failed = lines + verified, int(len(verified) > 1)
    print("\n".join(lines))
    return 1 if failed else 0
