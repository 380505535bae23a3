"""Hand poses of a plain video into a WiLoR-format file (`wilor_hands.json`, JSON lines: one
`{"frame_index", "left_pos": 21×3 | [], "right_pos": 21×3 | []}` per frame), estimated from its frames the
way a replay estimates them (every frame in order, the frames' own timestamps), so `convert`, `eval`, the
episode reader and the official tools can use them. Written under the output rule (output_safety): never over
the video, to a temporary file renamed at the end (an interrupted run leaves no half file)."""
from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path

from touchanything.app.sessions.replay_export import ReplaySummary
from touchanything.core.errors import UserError
from touchanything.core.output_safety import check_output, replacing
from touchanything.devices.camera_pose.estimator import CameraPoseConfig
from touchanything.devices.episodes.episode_loader import open_video_episode
from touchanything.devices.episodes.episode_streams import hands_row
from touchanything.devices.episodes.jsonl import json_line
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource


def write_pose_file(video: Path, out: Path, config: CameraPoseConfig = CameraPoseConfig(), overwrite: bool = False,
                    progress: Callable[[int, int], None] = lambda done, total: None) -> ReplaySummary:
    """Estimate the hands in every frame of `video` and write them to `out`; returns the frame count, the
    frames with each hand and the estimator's times (a ReplaySummary's pose fields). `progress(done, total)`
    is called once every input was checked (done 0), then after each frame. UserError before any work for an
    `out` that is not a .json file (the format's suffix: a reader would take a `.mp4` name for a video)."""
    video, out = Path(video), Path(out)
    if video.is_dir():
        raise UserError(f"{video}: a folder; pass a video file (an episode's chest.mp4, for example)")
    if out.suffix.lower() != ".json":
        raise UserError(f"{out}: the pose file is JSON lines and must be a .json file (wilor_hands.json beside an episode's "
                        "chest.mp4)")
    check_output(out, (video,), overwrite)
    with open_video_episode(video) as episode:
        source = ReplaySource(episode, ReplayConfig(speed=None, views=("ego",), pose_source="camera", camera_pose=config))
        summary = ReplaySummary()
        with contextlib.closing(source), replacing(out) as partial, open(partial, "w") as handle:
            progress(0, episode.num_frames)
            for snapshot in source:
                summary.add_pose(snapshot)
                summary.frames += 1
                handle.write(json_line(hands_row(snapshot.frame_index, snapshot.joints.reshape(2, 21, 3),
                                                 snapshot.joints_valid)))
                progress(summary.frames, episode.num_frames)
    return summary
