"""An episode replayed through the engine, the two ways the commands offer: into the dashboard (played in
real time) or into a comparison video (every frame, headless). The poses come from the episode's WiLoR file,
or, for a plain video, are estimated from its frames (`pose_source_for`)."""
from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from tqdm import tqdm

from touchanything.app.sessions.engine_choice import (
    ModelChoice,
    build_engine,
    illustrative_note,
    model_label,
    model_name,
    setting_name,
)
from touchanything.app.sessions.episode_summary import episode_lines
from touchanything.app.sessions.replay_export import ReplaySummary, export_replay, log_episode_videos
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.app.sessions.rerun_output import episode_name, finish, open_recording, session_properties
from touchanything.app.sessions.rerun_sink import RerunSink
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import is_plain_video, open_episode
from touchanything.devices.errors import UserError
from touchanything.devices.output_safety import check_output
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.viz.comparison_video import is_comparison_video
from touchanything.viz.dashboard.dashboard import Dashboard
from touchanything.viz.display import display_problem
from touchanything.viz.rerun_recording import RerunTarget


def replay_to_video(path: Path, choice: ModelChoice, views: tuple[str, ...], out: Path | None, hand3d: bool = False,
                    rerun: RerunTarget | None = None) -> ReplaySummary:
    """Export one episode into the comparison video `out` (None: none; `hand3d`: with the 3D hands panel) and
    the Rerun recording `rerun`; prints the episode, the summary and where the outputs are. The outputs were
    checked by the caller (`check_video_output`, `rerun_target`)."""
    engine = build_engine(choice, views)
    with open_episode(path) as episode:
        _require_ego(path, episode)
        pose_source = pose_source_for(episode)
        source = ReplaySource(episode, ReplayConfig(speed=None, views=views, pose_source=pose_source))
        caption = tuple(line for line in (model_name(choice), illustrative_note(choice, pose_source == "camera")) if line)
        print("\n".join(episode_lines(episode)))
        known = len(episode.problems)
        recording = rerun and open_recording(rerun, f"replay {episode_name(episode)}", session_properties(choice, engine, episode))
        try:
            with tqdm(total=episode.num_frames, unit="frame", desc="replay") as bar:
                summary = export_replay(source, engine, out, lambda frame: bar.update(1), hand3d, recording, caption,
                                        setting_name(choice, views))
        except BaseException:
            if recording is not None:
                recording.close()  # what was logged stays readable
            raise
        found = episode.problems[known:]  # what reading the frames found (a damaged chunk, an undecodable frame)
    if found:
        print(f"problems  {len(found)} more found while replaying")
        print("\n".join(f"  - {problem}" for problem in found))
    print(f"model     {model_label(choice, engine)}, {engine.runtime.capture}")
    print(f"setting   {setting_name(choice, views)}")
    if len(caption) > 1:
        print(f"note      {caption[1]}")
    print("\n".join(summary.lines()))
    if out is not None:
        print(f"video     {out}")
    if recording is not None:
        finish(recording)
    return summary


def check_video_output(out: Path, inputs: Iterable[Path | None], overwrite: bool) -> None:
    """Before any work: the comparison video `out` is an .mp4 and passes the output rule against the command's
    `inputs` (an earlier comparison video is replaced without `overwrite`)."""
    if out.suffix.lower() != ".mp4":
        raise UserError(f"{out}: the video must be an .mp4 file")
    check_output(out, inputs, overwrite, own=is_comparison_video)


def replay_in_dashboard(path: Path, choice: ModelChoice, views: tuple[str, ...], max_frames: int | None = None,
                        screenshot: Path | None = None, rerun: RerunTarget | None = None,
                        loop: bool = False, atlas: Path | None = None) -> Dashboard:
    """Play the episode in the dashboard until its window closes (or `max_frames` were rendered; then
    `screenshot` is saved); returns the closed dashboard (its stats, screenshots and session). A model
    that fails to load is reported in the dashboard, which then shows the cameras and the measured
    pressure only. `rerun`: everything shown also goes into that Rerun recording. `loop`: play the
    episode over and over (else hold at its end). `atlas`: the atlas the atlas panel shows (None: the
    committed one)."""
    with open_episode(path) as episode:
        _require_ego(path, episode)
        if problem := display_problem():
            raise UserError(f"cannot open the dashboard: {problem}; use --headless to write a video instead")
        try:
            engine, message = build_engine(choice, VIEW_NAMES), ""
        except UserError as exc:
            engine, message = None, f"no prediction: {exc}"
            print(message)
        session = ReplaySession(episode, engine, choice, message, pose_source_for(episode), loop)
        session.set_views(views)
        if atlas is not None:
            session.use_atlas(atlas)
        recording = rerun and open_recording(rerun, f"replay {episode_name(episode)}", session_properties(choice, engine, episode))
        if recording is not None:
            log_episode_videos(recording, episode, VIEW_NAMES)
            session.rerun = RerunSink(recording, session.bend, lambda snapshot: episode.timestamps_us[snapshot.frame_index] / 1e6)
        dashboard = Dashboard(session.start())
        try:
            dashboard.run(max_frames, screenshot)
        finally:
            if recording is not None:
                print(session.rerun.line())
                finish(recording, keep_serving=False)
        return dashboard


def pose_source_for(episode: Episode) -> str:
    """"camera" (estimated from the ego view) for a plain video, else "wilor" (the episode's WiLoR file)."""
    return "camera" if is_plain_video(episode) else "wilor"


def _require_ego(path: Path, episode: Episode) -> None:
    if episode.views.get("ego") is None:
        raise UserError(f"{path}: no ego (chest) video; the model needs it")
