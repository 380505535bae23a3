"""`touchanything split HDF5_ROOT`: build `split.json` with the official algorithm (seeded)."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.core.errors import DataError, UserError
from touchanything.core.output_safety import add_overwrite_argument, check_output
from touchanything.devices.episodes.dataset_split import (
    SPLIT_FILE,
    SPLIT_KEYS,
    SplitConfig,
    build_split,
    check_split_config,
    empty_split_problem,
    is_split_file,
    read_split,
    write_split,
)


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("split", help="build split.json (train/val/test_seen/test_unseen) for an HDF5 root")
    parser.add_argument("hdf5_root", type=Path, help="folder holding <Scene>/<task>/<id>.hdf5 trajectories")
    parser.add_argument("--out", type=Path, help="split file to write (default HDF5_ROOT/split.json)")
    parser.add_argument("--seed", type=int, default=SplitConfig.seed, help="shuffle seed (default 42)")
    parser.add_argument("--unseen-ratio", type=float, default=SplitConfig.unseen_ratio,
                        help="share of each scene's tasks held out as test_unseen (default 0.05)")
    parser.add_argument("--min-frames", type=int, default=SplitConfig.min_frames,
                        help="shorter trajectories are left out (default 30)")
    parser.add_argument("--min-wilor-valid", type=float, default=SplitConfig.min_wilor_valid,
                        help="trajectories with a smaller share of pose-valid frames are left out (default 0.3)")
    parser.add_argument("--allow-empty", action="store_true",
                        help="write the split even when its train or test lists are empty (refused otherwise)")
    parser.add_argument("--absolute", action="store_true", help="write absolute paths, as the official tool does")
    add_overwrite_argument(parser, "an existing split file (`convert` copies a split shipped with the raw data, e.g. the "
                           "simulator's object-aware one) or another file at --out")
    parser.set_defaults(run=run)


def existing_split(out: Path, overwrite: bool) -> str | None:
    """What an existing split file holds ("train 120, val 14, …") when it is kept (there, and no `overwrite`);
    None when there is none or it is to be replaced. An unreadable one is a UserError (kept too)."""
    if not out.exists() or overwrite:
        return None
    try:
        return ", ".join(f"{k} {len(v)}" for k, v in read_split(out).items())
    except DataError as exc:
        raise UserError(f"{exc}; it is kept: --overwrite replaces it, --out FILE writes another") from None


def run(args: argparse.Namespace) -> int:
    config = SplitConfig(args.seed, args.unseen_ratio, args.min_frames, args.min_wilor_valid)
    check_split_config(config)  # settings first: a bad value is named before any file is looked at
    out = args.out or args.hdf5_root / SPLIT_FILE
    check_output(out, (args.hdf5_root,), args.overwrite, own=is_split_file)
    if (held := existing_split(out, args.overwrite)) is not None:
        print(f"{out}: a split is already there ({held}); kept (--overwrite replaces it, --out FILE writes another)")
        return 0
    split, excluded = build_split(args.hdf5_root, config)
    if not args.allow_empty and (problem := empty_split_problem(split, excluded)):
        reasons = "; ".join(f"{path}: {reason}" for path, reason in list(excluded.items())[:2])
        raise UserError(f"{problem}; nothing written (--allow-empty writes it anyway)"
                        + (f"; excluded e.g. {reasons}" if reasons else ""))
    write_split(out, split, absolute=args.absolute)
    print(f"{out}: " + ", ".join(f"{k} {len(split[k])}" for k in SPLIT_KEYS) + f"; excluded {len(excluded)}")
    for path, reason in excluded.items():
        print(f"  excluded {path}: {reason}")
    return 0
