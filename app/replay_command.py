"""`touchanything replay PATH --out VIDEO.mp4`: an episode through the streaming engine, exported as a
comparison video (cameras; ground truth, prediction, error) with running metrics and latency."""
from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from app.info_command import episode_lines
from devices.episode_loader import open_episode
from devices.errors import UserError
from devices.snapshot import VIEW_NAMES
from inference.checkpoint import load_model
from inference.engine_config import EngineConfig
from inference.engine_runtime import RUNTIMES
from inference.streaming_engine import StreamingEngine
from viz.replay_export import ReplaySummary, export_replay

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
DEFAULT_CHECKPOINT = MODELS_DIR / "nano" / "best_model.pth"


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--checkpoint", type=Path, default=DEFAULT_CHECKPOINT,
                        help="model checkpoint (default: the bundled nano model)")
    parser.add_argument("--config", type=Path, help="config.yaml (default: beside the checkpoint)")
    parser.add_argument("--views", nargs="+", default=list(VIEW_NAMES), choices=VIEW_NAMES,
                        help="views the model uses (ego is required; default: all three)")
    parser.add_argument("--runtime", default="torch", choices=list(RUNTIMES))
    parser.add_argument("--precision", default="fp32", help="torch: fp32, bf16 (fp16 on GPU); onnx: fp32, int8")


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("replay", help="replay an episode through the engine into a comparison video")
    parser.add_argument("episode", type=Path, help="raw episode folder or .hdf5 trajectory")
    add_engine_arguments(parser)
    parser.add_argument("--out", type=Path, required=True, help="the comparison video to write (.mp4)")
    parser.set_defaults(run=run)


def engine_for(args: argparse.Namespace) -> StreamingEngine:
    views = tuple(v for v in VIEW_NAMES if v in args.views)
    return StreamingEngine(load_model(args.checkpoint, args.config),
                           EngineConfig(runtime=args.runtime, precision=args.precision, views=views))


def replay_to_video(path: Path, engine: StreamingEngine, out: Path) -> ReplaySummary:
    """Export one episode; prints the episode, the summary and where the video is."""
    if out.suffix.lower() != ".mp4":
        raise UserError(f"{out}: the video must be an .mp4 file")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{out.parent}: cannot create the output folder ({exc.strerror})") from None
    with open_episode(path) as episode:
        if episode.views.get("ego") is None:
            raise UserError(f"{path}: no ego (chest) video; the model needs it")
        print("\n".join(episode_lines(episode)))
        with tqdm(total=episode.num_frames, unit="frame", desc="replay") as bar:
            summary = export_replay(episode, engine, engine.config.views, out, lambda frame: bar.update(1))
    print("\n".join(summary.lines()))
    print(f"video     {out}")
    return summary


def run(args: argparse.Namespace) -> int:
    replay_to_video(args.episode, engine_for(args), args.out)
    return 0
