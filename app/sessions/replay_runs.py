"""An episode replayed through the engine, the two ways the commands offer: into the dashboard (played in
real time) or into a comparison video (every frame, headless). The poses come from the episode's WiLoR file,
or, for a plain video, are estimated from its frames (`pose_source_for`)."""
from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from touchanything.app.sessions.budget_watch import BudgetWatch
from touchanything.app.sessions.bundled import ATLAS_FILE
from touchanything.app.sessions.engine_choice import (
    ModelChoice,
    build_engine,
    illustrative_note,
    model_label,
    model_name,
)
from touchanything.app.sessions.episode_summary import episode_lines
from touchanything.app.sessions.replay_export import ReplaySummary, export_replay, log_episode_videos, tour_lines
from touchanything.app.sessions.replay_inputs import require_ego
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.app.sessions.rerun_output import episode_name, finish, open_recording, session_properties
from touchanything.app.sessions.rerun_sink import RerunSink
from touchanything.app.sessions.setting_choice import display_atlas, running_accuracy
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import is_plain_video, open_episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.viz.dashboard.dashboard import Dashboard
from touchanything.viz.display import display_problem
from touchanything.viz.rerun_recording import RerunTarget


def replay_to_video(paths: Sequence[Path], choice: ModelChoice, out: Path | None,
                    hand3d: bool = False, rerun: RerunTarget | None = None,
                    budget: BudgetWatch | None = None) -> list[ReplaySummary]:
    """Export the episodes, one after the other, through the choice's setting into the comparison video `out`
    (None: none; `hand3d`: with the 3D hands panel) and the Rerun recording `rerun` (one episode); prints each
    episode and its summary, for several the overall one, and where the outputs are; with the `budget` a setting
    was chosen for, says during the run when its steps go over it and after the run how they kept it. The
    episodes are opened before the model loads (a bad path is one line at once). The outputs were checked by
    the caller (`check_video_output`, `rerun_target`)."""
    views = choice.setting.views
    with contextlib.ExitStack() as opened:
        episodes = [opened.enter_context(open_episode(path)) for path in paths]
        for path, episode in zip(paths, episodes):
            require_ego(path, episode)
        engine = build_engine(choice)
        sources = [ReplaySource(e, ReplayConfig(speed=None, views=views, pose_source=pose_source_for(e))) for e in episodes]
        camera = any(pose_source_for(e) == "camera" for e in episodes)
        accuracy = running_accuracy(choice, display_atlas(ATLAS_FILE)[0]).line
        named = f"{model_name(choice)}; {accuracy}" if accuracy else model_name(choice)
        model = tuple(line for line in (named, illustrative_note(choice, camera)) if line)
        tour = [f"episode {k + 1} of {len(paths)}: {episode_name(e)}" for k, e in enumerate(episodes)] if len(paths) > 1 else []
        setting = choice.setting.name()
        footers = ([f"{setting} · episode {k + 1}/{len(paths)} {e.scene}/{e.task}" for k, e in enumerate(episodes)]
                   if tour else [setting])
        for k, episode in enumerate(episodes):
            print("\n".join(([f"--- {tour[k]}"] if tour else []) + episode_lines(episode)))
        known = [len(e.problems) for e in episodes]
        recording = rerun and open_recording(rerun, f"replay {episode_name(episodes[0])}",
                                             session_properties(choice, engine, episodes[0]))
        try:
            with tqdm(total=sum(e.num_frames for e in episodes), unit="frame", desc="replay") as bar:
                def frame_done(summary: ReplaySummary) -> None:
                    bar.update(1)
                    if budget is not None and (line := budget.during(summary.step_ms)):
                        bar.write(line)

                summaries = export_replay(sources, engine, out, frame_done, hand3d, recording, model, footers)
        except BaseException:
            if recording is not None:
                recording.close()  # what was logged stays readable
            raise
        for k, episode in enumerate(episodes):
            if found := episode.problems[known[k]:]:  # what reading the frames found (a damaged chunk, an undecodable frame)
                print(f"problems  {len(found)} more found while replaying" + (f" {episode_name(episode)}" if tour else ""))
                print("\n".join(f"  - {problem}" for problem in found))
    print(f"model     {model_label(choice, engine)}, {engine.runtime.capture}" + (f"; {accuracy}" if accuracy else ""))
    print(f"setting   {setting}")
    steps = [ms for s in summaries for ms in s.step_ms]
    if budget is not None and (line := budget.after(float(np.percentile(steps, 99)) if steps else None)):
        print(line)
    if len(model) > 1:
        print(f"note      {model[1]}")
    for k, summary in enumerate(summaries):
        print("\n".join(([f"--- {tour[k]}"] if tour else []) + summary.lines()))
    if tour:
        print("\n".join(["--- all episodes", *tour_lines(summaries)]))
    if out is not None:
        print(f"video     {out}")
    if recording is not None:
        finish(recording)
    return summaries


def replay_in_dashboard(path: Path, choice: ModelChoice, max_frames: int | None = None,
                        screenshot: Path | None = None, rerun: RerunTarget | None = None,
                        loop: bool = False, atlas: Path | None = None, tour: Sequence[Path] = (),
                        budget: BudgetWatch | None = None) -> Dashboard:
    """Play the episode in the dashboard (at the choice's setting) until its window closes (or `max_frames` were rendered; then
    `screenshot` is saved); returns the closed dashboard (its stats, screenshots and session). A model
    that fails to load is reported in the dashboard, which then shows the cameras and the measured
    pressure only. `rerun`: everything shown also goes into that Rerun recording. `loop`: play the
    episode over and over (else hold at its end). `atlas`: the atlas the atlas panel shows (None: the
    committed one). `tour`: more episodes, played after this one in turn, over and over (`ReplaySession`; not
    with `rerun`, whose recording holds one episode). `budget`: the budget the setting was chosen for (an overrun
    becomes the dashboard's message)."""
    with contextlib.ExitStack() as opened:
        episode, *others = [opened.enter_context(open_episode(p)) for p in (path, *tour)]
        for where, each in zip((path, *tour), (episode, *others)):
            require_ego(where, each)
        if problem := display_problem():
            raise UserError(f"cannot open the dashboard: {problem}; use --headless to write a video instead")
        try:
            engine, message = build_engine(choice.with_setting(views=VIEW_NAMES)), ""
        except UserError as exc:
            engine, message = None, f"no prediction: {exc}"
            print(message)
        session = ReplaySession(episode, engine, choice, message, pose_source_for(episode), loop, others)
        session.set_views(choice.setting.views)
        session.budget = budget
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
