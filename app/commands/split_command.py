"""`touchanything split HDF5_ROOT`: build `split.json` with the official algorithm (seeded)."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.devices.episodes.dataset_split import (
    SPLIT_FILE,
    SPLIT_KEYS,
    SplitConfig,
    build_split,
    empty_split_problem,
    write_split,
)
from touchanything.devices.errors import UserError


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("split", help="build split.json (train/val/test_seen/test_unseen) for an HDF5 root")
    parser.add_argument("hdf5_root", type=Path)
    parser.add_argument("--out", type=Path, help="split file to write (default HDF5_ROOT/split.json)")
    parser.add_argument("--seed", type=int, default=SplitConfig.seed)
    parser.add_argument("--unseen-ratio", type=float, default=SplitConfig.unseen_ratio,
                        help="share of each scene's tasks held out as test_unseen (default 0.05)")
    parser.add_argument("--min-frames", type=int, default=SplitConfig.min_frames)
    parser.add_argument("--min-wilor-valid", type=float, default=SplitConfig.min_wilor_valid)
    parser.add_argument("--allow-empty", action="store_true",
                        help="write the split even when its train or test lists are empty (refused otherwise)")
    parser.add_argument("--absolute", action="store_true", help="write absolute paths, as the official tool does")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    config = SplitConfig(args.seed, args.unseen_ratio, args.min_frames, args.min_wilor_valid)
    split, excluded = build_split(args.hdf5_root, config)
    out = args.out or args.hdf5_root / SPLIT_FILE
    if not args.allow_empty and (problem := empty_split_problem(split, excluded)):
        reasons = "; ".join(f"{path}: {reason}" for path, reason in list(excluded.items())[:2])
        raise UserError(f"{problem}; nothing written (--allow-empty writes it anyway)"
                        + (f"; excluded e.g. {reasons}" if reasons else ""))
    write_split(out, split, absolute=args.absolute)
    print(f"{out}: " + ", ".join(f"{k} {len(split[k])}" for k in SPLIT_KEYS) + f"; excluded {len(excluded)}")
    for path, reason in excluded.items():
        print(f"  excluded {path}: {reason}")
    return 0
