"""What syncing finished outputs to disk costs (docs/data_safety.md, "Synced before success").

    python benchmarks/fsync_cost.py [--rounds 3] [--out recordings/bench]

`convert`: the bundled sample (3 episodes, 900 frames, three 640×480 views, gzip level 1) converted with the
output rule as it is (every trajectory and report synced, then its folder) and with the syncs made no-ops,
interleaved round by round. `record`: what the recorder adds at its end through the rule — the glove grids
written from the recorded stream (`pressure_grids.npz`) and its folder — the same two ways, 20 times a round.
(The recorder's own periodic fsync of every stream, `fsync_s`, is measured in `bench/recorder_fsync.md`.)
Writes fsync_cost.json and .md.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from touchanything.app.sessions.bundled import SAMPLE_DIR, sample_episodes
from touchanything.core import output_safety
from touchanything.core.output_safety import replacing, write_text
from touchanything.devices.episodes.dataset_conversion import convert_dataset
from touchanything.devices.episodes.episode_files import read_pressure_grids, write_pressure_grids
from touchanything.devices.episodes.raw_episode import GRIDS_FILE


def timed(function, synced: bool) -> float:
    """Seconds `function()` takes with the output rule's syncs on or made no-ops."""
    saved = output_safety.sync, output_safety.fsync_path
    if not synced:
        output_safety.sync = output_safety.fsync_path = lambda path, directory=False: None
    try:
        start = time.perf_counter()
        function()
        return time.perf_counter() - start
    finally:
        output_safety.sync, output_safety.fsync_path = saved


def write_grids(path: Path, grids: np.ndarray) -> None:
    """What the recorder writes at its end, through the output rule."""
    with replacing(path) as part:
        write_pressure_grids(part, grids)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("recordings") / "bench")
    args = parser.parse_args()
    grids = read_pressure_grids(sample_episodes()[0] / GRIDS_FILE).grids
    times: dict[str, list[float]] = {k: [] for k in ("convert synced", "convert unsynced", "grids synced", "grids unsynced")}
    with tempfile.TemporaryDirectory(dir=".") as work:
        for round_index in range(args.rounds):
            for synced in (True, False):
                out = Path(work) / f"h5_{round_index}_{synced}"
                times[f"convert {'synced' if synced else 'unsynced'}"].append(
                    timed(lambda: convert_dataset(SAMPLE_DIR, out, compression_level=1), synced))
                shutil.rmtree(out)
                folder = Path(work) / "ep"
                folder.mkdir(exist_ok=True)
                times[f"grids {'synced' if synced else 'unsynced'}"].append(timed(
                    lambda: [write_grids(folder / GRIDS_FILE, grids) for _ in range(20)], synced) / 20)
    medians = {k: statistics.median(v) for k, v in times.items()}
    load = os.getloadavg()[0]
    record = {"rounds": args.rounds, "load_average": load, "seconds": times, "medians": medians,
              "convert_cost": medians["convert synced"] / medians["convert unsynced"] - 1,
              "grids_cost_ms": (medians["grids synced"] - medians["grids unsynced"]) * 1000}
    lines = ["# What syncing finished outputs costs (`benchmarks/fsync_cost.py`)", "",
             f"Medians of {args.rounds} interleaved rounds on {os.cpu_count()} CPU cores, load average {load:.1f} at the end "
             "(other jobs on the machine).", "", "| measured | synced | not synced | cost |",
             "|---|---|---|---|",
             f"| convert the sample (3 trajectories, 900 frames) | {medians['convert synced']:.2f} s | "
             f"{medians['convert unsynced']:.2f} s | {record['convert_cost']:+.1%} |",
             f"| the recording's grids at its end (pressure_grids.npz, {grids.nbytes / 1e6:.1f} MB of grids) | "
             f"{medians['grids synced'] * 1000:.1f} ms | {medians['grids unsynced'] * 1000:.1f} ms | "
             f"{record['grids_cost_ms']:+.1f} ms |"]
    write_text(args.out / "fsync_cost.json", json.dumps(record, indent=1) + "\n")
    write_text(args.out / "fsync_cost.md", "\n".join(lines) + "\n")
    print("\n".join(lines))
    print(np.round([medians[k] for k in medians], 3))


if __name__ == "__main__":
    main()
