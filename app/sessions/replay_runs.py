"""An episode replayed through the engine, the two ways the commands offer: into the dashboard (played in
real time) or into a comparison video (every frame, headless). The poses come from the episode's WiLoR file,
or, for a plain video, are estimated from its frames (`pose_source_for`)."""
from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from touchanything.app.sessions.engine_choice import ModelChoice, build_engine, model_label
from touchanything.app.sessions.episode_summary import episode_lines
from touchanything.app.sessions.replay_export import ReplaySummary, export_replay
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import is_plain_video, open_episode
from touchanything.devices.errors import UserError
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.viz.dashboard.dashboard import Dashboard
from touchanything.viz.display import display_problem


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
        source = ReplaySource(episode, ReplayConfig(speed=None, views=views, pose_source=pose_source_for(episode)))
        print("\n".join(episode_lines(episode)))
        with tqdm(total=episode.num_frames, unit="frame", desc="replay") as bar:
            summary = export_replay(source, engine, out, lambda frame: bar.update(1))
    print(f"model     {model_label(choice, engine)}, {engine.runtime.capture}")
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
        session = ReplaySession(episode, engine, choice, message, pose_source_for(episode))
        session.set_views(views)
        dashboard = Dashboard(session.start())
        dashboard.run(max_frames, screenshot)
        return dashboard


def pose_source_for(episode: Episode) -> str:
    """"camera" (estimated from the ego view) for a plain video, else "wilor" (the episode's WiLoR file)."""
    return "camera" if is_plain_video(episode) else "wilor"


def _require_ego(path: Path, episode: Episode) -> None:
    if episode.views.get("ego") is None:
        raise UserError(f"{path}: no ego (chest) video; the model needs it")
