"""`touchanything grids EPISODE...`: (re)compute `pressure_grids.npz` from `jq_pressure.json`."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from touchanything.core.errors import DataError, require_finite_positive
from touchanything.core.output_safety import add_overwrite_argument, check_output, named
from touchanything.core.snapshot import HANDS
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.tactile_pipeline import TactileConfig


def broken_column(text: str) -> tuple[str, int]:
    """Parse `HAND:COLUMN`, e.g. `right:9` (display column 0–20)."""
    hand, _, column = text.partition(":")
    if hand not in HANDS or not column.isdigit() or not 0 <= int(column) <= 20:
        raise argparse.ArgumentTypeError(f"expected HAND:COLUMN with HAND left or right and COLUMN 0–20, got {text!r}")
    return hand, int(column)


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("grids", help="compute pressure_grids.npz of episodes from their jq_pressure.json")
    parser.add_argument("episodes", type=Path, nargs="+", metavar="EPISODE", help="raw episode folders")
    parser.add_argument("--layout", type=Path, help="folder with the two mapping files and hand_joint_positions.json "
                        "(default: the project's own layout)")
    parser.add_argument("--repair-column", type=broken_column, action="append", default=[], metavar="HAND:COLUMN",
                        help="interpolate a broken display column from its neighbours (repeatable; default: none)")
    parser.add_argument("--min-scale", type=float, default=TactileConfig.min_scale,
                        help="smallest normalisation divisor in raw units (default 60: sensor noise stays below the contact threshold)")
    add_overwrite_argument(parser, "a pressure_grids.npz that touchanything did not write (an official episode's, a copy)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Every episode is tried; one that cannot be computed is named on stderr, its grids left as they were,
    and the exit status is 1. Glove samples left out of grids that were computed (malformed lines, non-finite or
    out-of-range values) are named, one line per episode; the exit status stays 0."""
    from touchanything.devices.episodes.episode_streams import read_glove
    from touchanything.devices.episodes.episode_writer import write_grids_from_glove
    from touchanything.devices.episodes.raw_episode import GLOVE_FILE, GRIDS_FILE, episode_file

    require_finite_positive("--min-scale", args.min_scale)
    layout = TactileLayout.from_dir(args.layout) if args.layout else TactileLayout.default()
    config = TactileConfig(broken_columns=tuple(args.repair_column), min_scale=args.min_scale)
    for folder in args.episodes:  # every output checked before any work
        check_output(folder / GRIDS_FILE, (episode_file(folder, GLOVE_FILE), args.layout), args.overwrite,
                     own=named(GRIDS_FILE))
    failed = 0
    for folder in args.episodes:
        try:
            grids = write_grids_from_glove(folder, layout, config)
        except DataError as exc:
            print(f"touchanything grids: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        print(f"{folder}: {len(grids.grids)} frames; baseline corrected left {grids.baseline_applied[0]}, "
              f"right {grids.baseline_applied[1]}; tactile max {grids.tactile_max.round(1).tolist()}, "
              f"bend max {grids.bend_max.round(1).tolist()}")
        glove = episode_file(folder, GLOVE_FILE)
        if skipped := read_glove(glove)[0].skipped():
            print(f"{glove}: {skipped}")
    return 1 if failed else 0
