"""`touchanything demo [EPISODE]`: the bundled sample through the bundled model, exported as a comparison
video (cameras; measured, predicted and error pressure maps) with running metrics and latency."""
from __future__ import annotations

import argparse
from pathlib import Path

from devices.episode_loader import find_raw_episodes
from devices.errors import UserError
from inference.checkpoint import load_model
from inference.engine_config import EngineConfig
from inference.streaming_engine import StreamingEngine

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "recordings" / "sample"
DEMO_VIDEO = SAMPLE_DIR.parent / "demo.mp4"


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("demo", help="the bundled sample through the bundled model, as a comparison video")
    parser.add_argument("episode", type=Path, nargs="?", help="episode folder or .hdf5 (default: the bundled sample)")
    parser.add_argument("--out", type=Path, default=DEMO_VIDEO, help=f"video to write (default: {DEMO_VIDEO})")
    parser.set_defaults(run=run)


def sample_episodes() -> list[Path]:
    """The bundled sample episodes (raw folders under recordings/sample)."""
    return find_raw_episodes(SAMPLE_DIR) if SAMPLE_DIR.is_dir() else []


def run(args: argparse.Namespace) -> int:
    from app.replay_command import DEFAULT_CHECKPOINT, replay_to_video

    path = args.episode
    if path is None:
        samples = sample_episodes()
        if not samples:
            raise UserError(f"{SAMPLE_DIR}: no bundled sample episode found; pass an episode path")
        path = samples[0]
    replay_to_video(path, StreamingEngine(load_model(DEFAULT_CHECKPOINT), EngineConfig()), args.out)
    return 0
