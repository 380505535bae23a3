"""Headless replay: every frame of an episode through the streaming engine into a comparison video (drawn by
`touchanything.viz.replay_frame`), with running official metrics and engine latency, and a summary at the end."""
from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.devices.camera_pose.estimator import STAGE
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.devices.rig.replay import ReplaySource
from touchanything.devices.snapshot import Snapshot
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.comparison_video import write_comparison_video
from touchanything.viz.contact import hand_contact
from touchanything.viz.replay_frame import ReplayFrameRenderer, metric_text
from touchanything.viz.rerun_recording import RerunRecording


@dataclass
class ReplaySummary:
    """frames written; predicted: frames with a prediction for at least one hand; no_pose: frames the engine
    answered without a valid hand pose to predict from (no contact in the metrics); metrics: cumulative
    official metrics (None without ground truth); latency_ms / step_ms: per-prediction latency and engine
    step times; hands: frames with a valid pose per hand [left, right]; pose_source: where the poses came
    from; pose_ms: the hand-pose estimator's time per frame (camera poses only); lamps_agree / lamps_shown:
    per hand [left, right], the predicted frames with ground truth whose predicted and measured contact lamps
    agree, and all of them."""

    frames: int = 0
    predicted: int = 0
    no_pose: int = 0
    metrics: dict[str, float] | None = None
    latency_ms: list[float] = field(default_factory=list)
    step_ms: list[float] = field(default_factory=list)
    hands: list[int] = field(default_factory=lambda: [0, 0])
    pose_source: str = ""
    pose_ms: list[float] = field(default_factory=list)
    lamps_agree: list[int] = field(default_factory=lambda: [0, 0])
    lamps_shown: int = 0

    def add_lamps(self, predicted: np.ndarray, measured: np.ndarray) -> None:
        """Count one frame's (2,) bool contact lamps, predicted against measured."""
        self.lamps_agree = [n + int(p == m) for n, p, m in zip(self.lamps_agree, predicted, measured)]
        self.lamps_shown += 1

    def lamp_line(self) -> str:
        """"contact   lamps agree on 91.2 % of the predicted frames (left 90.1 %, right 92.3 %; 300 frames)"."""
        left, right = (100 * n / self.lamps_shown for n in self.lamps_agree)
        return (f"contact   lamps agree on {(left + right) / 2:.1f} % of the predicted frames (left {left:.1f} %, "
                f"right {right:.1f} %; {self.lamps_shown} frames)")

    def add_pose(self, snapshot: Snapshot) -> None:
        self.hands = [n + int(v) for n, v in zip(self.hands, snapshot.joints_valid)]
        self.pose_source = snapshot.pose_source or self.pose_source
        if STAGE in snapshot.stage_ms:
            self.pose_ms.append(snapshot.stage_ms[STAGE])

    def pose_line(self) -> str:
        """"poses     camera estimate: left hand in 40, right hand in 38 of 60 frames; 14.2 ms per frame (p99 …)"."""
        line = (f"poses     {self.pose_source or 'none'}: left hand in {self.hands[0]}, right hand in {self.hands[1]} "
                f"of {self.frames} frames")
        if self.pose_ms:
            pose_ms = np.percentile(self.pose_ms, [50, 99])
            line += f"; {pose_ms[0]:.1f} ms per frame (p99 {pose_ms[1]:.1f})"
        return line

    def lines(self) -> list[str]:
        no_pose = f", {self.no_pose} without a hand pose (nothing predicted)" if self.no_pose else ""
        out = [f"frames    {self.frames} written, {self.predicted} with a prediction{no_pose}", self.pose_line()]
        if self.metrics is None:
            out.append("metrics   n/a (the episode has no ground-truth pressure)")
        elif not self.predicted:
            out.append("metrics   n/a (no frame had a hand pose to predict from)")
        else:
            out.append("metrics   " + ", ".join(f"{k} {metric_text(v)}" for k, v in self.metrics.items()
                                                if k != "mae_left" and k != "mae_right"))
        if self.lamps_shown and self.predicted:
            out.append(self.lamp_line())
        if self.step_ms:
            step, latency = np.percentile(self.step_ms, [50, 99]), np.percentile(self.latency_ms, [50, 99])
            out.append(f"engine    {step[0]:.1f} ms per frame (p99 {step[1]:.1f}); latency p50 {latency[0]:.1f} ms, "
                       f"p99 {latency[1]:.1f} ms")
        return out


def replay_frames(source: ReplaySource, engine: StreamingEngine, summary: ReplaySummary,
                  progress: Callable[[int], None] = lambda frame: None, renderer: ReplayFrameRenderer | None = None,
                  rerun: RerunRecording | None = None) -> Iterator[np.ndarray | None]:
    """Yield, for every frame of the source's episode (a ReplaySource with speed None: every frame is
    processed), its comparison frame drawn by `renderer` (None: nothing is drawn, None is yielded) and log
    it to `rerun` when given; the source is closed at the end."""
    episode = source.episode
    gt = None
    if episode.pressure is not None:
        gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
    bend = TactileLayout.default().bend
    metrics = RunningMetrics(bend) if gt is not None else None
    engine.reset()
    if rerun is not None:
        log_episode_videos(rerun, episode, source.config.views)
    latest: Prediction | None = None
    with contextlib.closing(source):
        for snapshot in source:
            summary.add_pose(snapshot)
            for prediction in engine.step(snapshot):
                latest = prediction
                summary.latency_ms.append(prediction.latency_ms)
                if "total" in prediction.timings_ms:
                    summary.step_ms.append(prediction.timings_ms["total"])
            shown = latest.pressure if latest is not None and latest.frame_index == snapshot.frame_index else None
            truth = gt[snapshot.frame_index] if gt is not None else None
            if shown is not None:
                summary.predicted += any(latest.hands_predicted)
                summary.no_pose += not any(latest.hands_predicted)
                if metrics is not None:
                    metrics.add(shown, truth)
                    summary.add_lamps(hand_contact(shown, bend), hand_contact(truth, bend))
            summary.frames += 1
            if rerun is not None:
                _log_frame(rerun, episode, snapshot, truth, latest if shown is not None else None, metrics, bend)
            progress(snapshot.frame_index)
            yield None if renderer is None else renderer.render(snapshot, truth, shown, latest, metrics)
    summary.metrics = metrics.cumulative() if metrics is not None else None


def log_episode_videos(rerun: RerunRecording, episode: Episode, views: tuple[str, ...]) -> None:
    """The episode's own MP4 files of `views` as video assets (the other views go frame by frame)."""
    videos = {v: s.path for v, s in episode.views.items() if v in views and type(s) is VideoReader and s.path.suffix == ".mp4"}
    rerun.log_videos(videos, episode.num_frames, episode.timestamps_us / 1e6,
                     {v: (episode.views[v].width, episode.views[v].height) for v in videos})


def _log_frame(rerun: RerunRecording, episode: Episode, snapshot: Snapshot, truth: np.ndarray | None,
               prediction: Prediction | None, metrics: RunningMetrics | None, bend: np.ndarray) -> None:
    """One replayed frame into the recording: what the episode holds, and the prediction of this frame."""
    time_s = float(episode.timestamps_us[snapshot.frame_index]) / 1e6
    rerun.log_observation(snapshot.frame_index, time_s, snapshot.images, snapshot.joints, snapshot.joints_valid, truth,
                          hand_contact(truth, bend), snapshot.trackers)
    if prediction is not None:
        rerun.log_prediction(snapshot.frame_index, time_s, prediction.pressure, hand_contact(prediction.pressure, bend),
                             snapshot.joints, snapshot.joints_valid, truth, prediction.latency_ms,
                             prediction.timings_ms.get("total"), metrics and metrics.rolling(), metrics and metrics.cumulative())


def export_replay(source: ReplaySource, engine: StreamingEngine, out: Path | None,
                  progress: Callable[[int], None] = lambda frame: None, hand3d: bool = False,
                  rerun: RerunRecording | None = None, caption: tuple[str, ...] = (), setting: str = "") -> ReplaySummary:
    """Write the comparison video of the source's whole episode to `out` (H.264 MP4; None: no video) with the
    3D hands panel when `hand3d`, `caption` (what the model is, a warning) under the predicted maps, `setting`
    (the engine setting's name) in the footer, and the Rerun recording when given; return the summary."""
    summary = ReplaySummary()
    if out is None:
        for _ in replay_frames(source, engine, summary, progress, rerun=rerun):
            pass
        return summary
    renderer = ReplayFrameRenderer(source.episode.num_frames, TactileLayout.default().bend, hand3d, caption, setting)
    write_comparison_video(out, replay_frames(source, engine, summary, progress, renderer, rerun))
    return summary
