"""`touchanything replay PATH`: an episode through the streaming engine in the dashboard, or with
`--headless` exported as a comparison video (cameras; ground truth, prediction, error) with running
metrics and latency."""
from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from touchanything.app.commands.info_command import episode_lines
from touchanything.app.sessions.engine_choice import ModelChoice, build_engine, default_checkpoint
from touchanything.app.sessions.replay_export import ReplaySummary, export_replay
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.inference.engine.engine_runtime import RUNTIMES
from touchanything.viz.dashboard.dashboard import Dashboard
from touchanything.viz.display import display_problem

RECORDINGS = Path("recordings")


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--checkpoint", type=Path, default=default_checkpoint(),
                        help="model checkpoint (default: the bundled nano model)")
    parser.add_argument("--config", type=Path, help="config.yaml (default: beside the checkpoint)")
    parser.add_argument("--views", nargs="+", default=list(VIEW_NAMES), choices=VIEW_NAMES,
                        help="views the model uses (ego is required for a prediction; default: all three)")
    parser.add_argument("--runtime", default="torch", choices=list(RUNTIMES))
    parser.add_argument("--precision", default="fp32", help="torch: fp32, bf16 (fp16 on GPU); onnx: fp32, int8")


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("replay", help="replay an episode through the engine in the dashboard, or into a video")
    parser.add_argument("episode", type=Path, help="raw episode folder or .hdf5 trajectory")
    add_engine_arguments(parser)
    parser.add_argument("--headless", action="store_true", help="no window: write the comparison video instead")
    parser.add_argument("--out", type=Path, help="the comparison video to write (.mp4; implies --headless; "
                                                  "default recordings/<trajectory>_replay.mp4)")
    parser.set_defaults(run=run)


def model_choice(args: argparse.Namespace) -> ModelChoice:
    return ModelChoice(args.checkpoint, args.config, args.runtime, args.precision)


def selected_views(args: argparse.Namespace) -> tuple[str, ...]:
    return tuple(v for v in VIEW_NAMES if v in args.views)


def replay_to_video(path: Path, choice: ModelChoice, views: tuple[str, ...], out: Path) -> ReplaySummary:
    """Export one episode; prints the episode, the summary and where the video is."""
    if out.suffix.lower() != ".mp4":
        raise UserError(f"{out}: the video must be an .mp4 file")
    engine = build_engine(choice, views)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{out.parent}: cannot create the output folder ({exc.strerror})") from None
    with open_episode(path) as episode:
        _require_ego(path, episode)
        print("\n".join(episode_lines(episode)))
        with tqdm(total=episode.num_frames, unit="frame", desc="replay") as bar:
            summary = export_replay(episode, engine, views, out, lambda frame: bar.update(1))
    print("\n".join(summary.lines()))
    print(f"video     {out}")
    return summary


def replay_in_dashboard(path: Path, choice: ModelChoice, views: tuple[str, ...], max_frames: int | None = None,
                        screenshot: Path | None = None) -> Dashboard:
    """Play the episode in the dashboard until its window closes (or `max_frames` were rendered; then
    `screenshot` is saved); returns the closed dashboard (its stats, screenshots and session). A model
    that fails to load is reported in the dashboard, which then shows the cameras and the measured
    pressure only."""
    with open_episode(path) as episode:
        _require_ego(path, episode)
        if problem := display_problem():
            raise UserError(f"cannot open the dashboard: {problem}; use --headless to write a video instead")
        try:
            engine, message = build_engine(choice, VIEW_NAMES), ""
        except UserError as exc:
            engine, message = None, f"no prediction: {exc}"
            print(message)
        session = ReplaySession(episode, engine, choice, message)
        session.set_views(views)
        dashboard = Dashboard(session.start())
        dashboard.run(max_frames, screenshot)
        return dashboard


def _require_ego(path: Path, episode: Episode) -> None:
    if episode.views.get("ego") is None:
        raise UserError(f"{path}: no ego (chest) video; the model needs it")


def default_video(path: Path) -> Path:
    return RECORDINGS / f"{path.resolve().name.removesuffix('.hdf5')}_replay.mp4"


def run(args: argparse.Namespace) -> int:
    if args.headless or args.out is not None:
        replay_to_video(args.episode, model_choice(args), selected_views(args), args.out or default_video(args.episode))
    else:
        stats = replay_in_dashboard(args.episode, model_choice(args), selected_views(args)).stats
        print(f"dashboard closed after {stats.frames} frames ({stats.fps:.0f} fps)")
    return 0
