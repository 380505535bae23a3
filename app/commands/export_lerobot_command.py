"""`touchanything export-lerobot ROOT OUT`: raw episode folders and HDF5 trajectories as a LeRobot v3.0 dataset
(the three views as video features, both hands' joints, the 21×21 maps per hand, the tracker poses, the task text,
the fps and every frame's capture time, which pictures stand in for frames the source did not decode;
docs/data_formats.md, "LeRobot datasets"). Damage is one `damaged` line per episode, exit status 0; an episode that
cannot be exported is one `skipped` line, exit status 1."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.core.errors import UserError
from touchanything.core.input_paths import collect_inputs
from touchanything.core.output_safety import add_overwrite_argument, check_output, check_outside
from touchanything.core.view_sets import view_set_name
from touchanything.devices.episodes.lerobot_format import ACTION_CHOICES

if TYPE_CHECKING:
    from tqdm import tqdm


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("export-lerobot", help="export episodes as a LeRobot v3.0 dataset")
    parser.add_argument("root", type=Path, help="dataset root (raw episode folders and/or .hdf5 files), or one episode")
    parser.add_argument("out", type=Path, help="the dataset folder to write (meta/, data/, videos/)")
    parser.add_argument("--action", metavar="FEATURE", default=None,
                        help=f"write this feature as LeRobot's `action` instead of under its own name ({', '.join(ACTION_CHOICES)}; "
                             "e.g. observation.tactile to train a LeRobot policy to predict the pressure); off by default")
    add_overwrite_argument(parser, "OUT")
    parser.set_defaults(run=run)


def check_export_output(root: Path, out: Path, overwrite: bool) -> None:
    """Before any work: OUT lies inside no input folder — ROOT, nor a folder a link in it reaches (an episode stored
    elsewhere), named with that link — nor holds ROOT, and passes the output rule."""
    for source in collect_inputs((root,)).paths:
        try:
            check_outside(out, (source.resolved,))
        except UserError:
            raise UserError(f"{out}: the output would lie inside the input {source.named()}; choose a folder outside it") from None
    check_output(out, (root,), overwrite, whole=True)


def _show(bar: tqdm, written: int, total: int) -> None:
    """Move the progress bar to `written` of `total` episode frames."""
    bar.total = total
    bar.update(written - bar.n)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from touchanything.devices.episodes.lerobot_export import check_action, export_lerobot, source_episodes

    check_action(args.action)
    if not args.root.exists():
        raise UserError(f"{args.root}: not found")
    check_export_output(args.root, args.out, args.overwrite)
    sources = source_episodes(args.root)
    if not sources:
        raise UserError(f"{args.root}: no episodes found (raw folders with chest.mp4, or .hdf5 files)")
    with tqdm(unit="frame", desc="export") as bar:
        summary = export_lerobot(args.root, args.out, args.overwrite, args.action, lambda written, total: _show(bar, written, total))
    size = sum(p.stat().st_size for p in args.out.rglob("*") if p.is_file()) / 1e6
    print(f"exported  {summary.episodes} episodes, {summary.frames} frames, views {view_set_name(summary.views)}; "
          f"{size:.1f} MB in {args.out}")
    for line in summary.damaged:
        print(f"damaged   {line}")
    for problem in summary.skipped:
        print(f"skipped   {problem}")
    print(f"read it   touchanything info {args.out}; replay {args.out}/episode_000000; "
          f"LeRobotDataset(repo_id=..., root=\"{args.out}\")")
    return 1 if summary.skipped else 0
