"""`touchanything convert RAW_ROOT OUT_ROOT`: raw EgoTouch folders → HDF5, with a progress bar and reports."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.core.output_safety import add_overwrite_argument


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("convert", help="convert raw EgoTouch episode folders to HDF5")
    parser.add_argument("raw_root", type=Path, help="folder holding <Scene>/<task>/<trajectory_id>/ episodes")
    parser.add_argument("out_root", type=Path, help="output folder for <Scene>/<task>/<trajectory_id>.hdf5")
    parser.add_argument("--workers", type=int, default=1, help="trajectories converted in parallel (default 1)")
    parser.add_argument("--compression-level", type=int, default=4, help="gzip level 0–9, 0 = none (default 4)")
    parser.add_argument("--skip-existing", action="store_true",
                        help="leave trajectories this command already converted from the same episode (complete ones: "
                             "they carry its mark)")
    add_overwrite_argument(parser, "a file at a trajectory's path that is not this command's conversion of that episode, "
                           "or a conversion_report.txt or quality_report.txt in OUT_ROOT that it did not write")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.progress_bar import ProgressBar
    from touchanything.devices.episodes.dataset_conversion import (
        CONVERSION_REPORT,
        QUALITY_REPORT,
        convert_dataset,
        damaged_line,
    )

    bars: list[ProgressBar] = []  # the bar appears once the inputs and outputs were checked (an error is one line)
    frames, failed = [0], [0]

    def progress(result) -> None:
        frames[0] += result.frames
        failed[0] += result.status == "failed"
        bars[0].set_postfix(frames=frames[0], failed=failed[0], refresh=False)
        bars[0].update(1)
        if result.status == "failed":
            bars[0].write(f"failed: {result.error}")
        elif damaged := damaged_line(result):
            bars[0].write(damaged)

    try:
        results = convert_dataset(args.raw_root, args.out_root, args.workers, args.compression_level,
                                  args.skip_existing, on_result=progress,
                                  on_start=lambda total: bars.append(ProgressBar(total=total, unit="traj", desc="convert")),
                                  overwrite=args.overwrite, on_note=lambda line: bars[0].write(line))
    finally:
        for bar in bars:
            bar.close()
    report = args.out_root / CONVERSION_REPORT
    print(  # the report's summary line: the same numbers, labelled wall time and per worker
        report.read_text().splitlines()[0])
    print(f"reports: {report}, {args.out_root / QUALITY_REPORT}")
    # a damaged trajectory holds what its episode gave, the rest marked invalid or cut: a faithful output (exit 0)
    return 1 if any(r.status == "failed" for r in results) else 0
