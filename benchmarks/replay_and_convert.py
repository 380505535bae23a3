"""Benchmark: replay decode speed of a 640×480 three-view episode, and raw → HDF5 conversion throughput.

    .venv/bin/python benchmarks/replay_and_convert.py [--seconds 10] [--out docs/bench/foundation.json]

Writes a synthetic episode (textured moving pictures, H.264 as the writer produces), replays it as fast as
possible through ReplaySource (all three views decoded to RGB), then converts it with gzip level 4.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.episodes.episode_writer import EpisodeFrame, RawEpisodeWriter
from touchanything.devices.episodes.hdf5_convert import convert_trajectory
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource


def textured_frame(view: int, frame: int, texture: np.ndarray) -> np.ndarray:
    """A 480×640 view of a large texture, panning over time (realistic decode cost)."""
    y, x = (frame * 3 + 40 * view) % 240, (frame * 5 + 70 * view) % 320
    return texture[y:y + 480, x:x + 640]


def write_benchmark_episode(folder: Path, frames: int) -> None:
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 256, size=(90, 120, 3), dtype=np.uint8).repeat(8, 0).repeat(8, 1)
    joints = rng.uniform(-3, 3, size=(2, 21, 3)).astype(np.float32)
    joints[..., 2] += 50
    with RawEpisodeWriter(folder) as writer:
        for i in range(frames):
            raw = rng.integers(0, 40, size=(2, 256), dtype=np.uint8)
            writer.write(EpisodeFrame(
                images={v: textured_frame(k, i, texture) for k, v in enumerate(VIEW_NAMES)},
                wilor=(joints, np.array([True, True])),
                glove=(raw, np.array([True, True]), np.tile(np.array([1.0, 0, 0, 0], np.float32), (2, 1))),
            ))


def measure(seconds: float) -> dict:
    frames = int(seconds * 30)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "Bench" / "task" / "episode"
        started = time.perf_counter()
        write_benchmark_episode(folder, frames)
        write_s = time.perf_counter() - started
        with open_episode(folder) as episode:
            started = time.perf_counter()
            count = sum(1 for _ in ReplaySource(episode, ReplayConfig(speed=None)))
            replay_s = time.perf_counter() - started
        started = time.perf_counter()
        result = convert_trajectory(folder, Path(tmp) / "episode.hdf5", compression_level=4)
        convert_s = time.perf_counter() - started
        hdf5_mb = (Path(tmp) / "episode.hdf5").stat().st_size / 2**20
        with open_episode(Path(tmp) / "episode.hdf5") as episode:
            started = time.perf_counter()
            sum(1 for _ in ReplaySource(episode, ReplayConfig(speed=None)))
            hdf5_replay_s = time.perf_counter() - started
    assert count == frames and result.status == "converted", result.error
    return {
        "frames": frames, "views": 3, "resolution": "640x480",
        "write_fps": frames / write_s,
        "replay_raw_fps": frames / replay_s, "replay_raw_x_realtime": frames / 30 / replay_s,
        "replay_hdf5_fps": frames / hdf5_replay_s, "replay_hdf5_x_realtime": frames / 30 / hdf5_replay_s,
        "convert_fps": frames / convert_s, "hdf5_mb": hdf5_mb,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    figures = measure(args.seconds)
    for key, value in figures.items():
        print(f"{key:24s} {value:.1f}" if isinstance(value, float) else f"{key:24s} {value}")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
