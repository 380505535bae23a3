"""`touchanything demo [EPISODE]`: replay an episode (default: the bundled sample) and summarise it."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from app.info_command import episode_lines
from devices.episode_loader import find_raw_episodes, open_episode
from devices.errors import UserError
from devices.replay import ReplayConfig, ReplaySource

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "recordings" / "sample"


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("demo", help="replay the bundled sample episode and summarise it")
    parser.add_argument("episode", type=Path, nargs="?", help="episode folder or .hdf5 (default: the bundled sample)")
    parser.set_defaults(run=run)


def sample_episodes() -> list[Path]:
    """The bundled sample episodes (raw folders under recordings/sample)."""
    return find_raw_episodes(SAMPLE_DIR) if SAMPLE_DIR.is_dir() else []


def run(args: argparse.Namespace) -> int:
    path = args.episode
    if path is None:
        samples = sample_episodes()
        if not samples:
            raise UserError(f"{SAMPLE_DIR}: no bundled sample episode found; pass an episode path")
        path = samples[0]
    with open_episode(path) as episode:
        started = time.perf_counter()
        frames = views = 0
        for snapshot in ReplaySource(episode, ReplayConfig(speed=None)):
            frames += 1
            views += len(snapshot.images)
        elapsed = max(time.perf_counter() - started, 1e-9)
        if frames == 0:
            raise UserError(f"{path}: no frames to replay")
        print("\n".join(episode_lines(episode)))
        realtime = frames / episode.fps / elapsed
        print(f"replay    {frames} frames, {views} camera images in {elapsed:.2f} s "
              f"({frames / elapsed:.0f} frames/s, {realtime:.1f}× real time)")
    return 0
