"""The training frame cache's first build on this machine: the wall time to decode and resize N trajectories
(raw episode folders or HDF5 files) into a new cache, in 1 and in 2 (or more) processes, rounds interleaved.

    python benchmarks/frame_cache_build.py TRAJECTORY... [--size 64] [--workers 1 2] [--rounds 2] [--out REPORT.md]

Each round builds every trajectory into an empty temporary cache, once per worker count; the report gives each
build's seconds, per trajectory, and the speed-up over one process (median of the rounds), with the load average
each build started at (other processes share the cores).
"""
from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.training.frame_cache import FrameCache


def build_seconds(trajectories: list[Path], size: int, workers: int) -> float:
    """Wall seconds to build every trajectory's entry (all views) into an empty cache."""
    with tempfile.TemporaryDirectory() as folder:
        cache = FrameCache(Path(folder), size)
        start = time.perf_counter()
        cache.build([(path, tuple(VIEW_NAMES)) for path in trajectories], workers)
        return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trajectories", nargs="+", type=Path)
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    if missing := [str(path) for path in args.trajectories if not path.exists()]:
        parser.error(f"no such trajectory: {', '.join(missing)}")
    times: dict[int, list[float]] = {w: [] for w in args.workers}
    rows = []
    for round_ in range(args.rounds):
        for workers in args.workers:
            load = os.getloadavg()[0]
            seconds = build_seconds(args.trajectories, args.size, workers)
            times[workers].append(seconds)
            rows.append(f"| {round_ + 1} | {workers} | {seconds:.1f} | {seconds / len(args.trajectories):.2f} | {load:.1f} |")
    base = statistics.median(times[args.workers[0]])
    lines = [f"# Frame cache: first build ({len(args.trajectories)} trajectories at {args.size} px)", "",
             f"{os.cpu_count()} CPU cores ({platform.machine()}); `python benchmarks/frame_cache_build.py` "
             f"over {args.trajectories[0].parent} and others.", "",
             "| round | processes | seconds | s per trajectory | load average at start |", "|---|---|---|---|---|",
             *rows, "", *(f"- {w} processes: median {statistics.median(t):.1f} s, "
                          f"{base / statistics.median(t):.2f}× the speed of {args.workers[0]}" for w, t in times.items())]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
