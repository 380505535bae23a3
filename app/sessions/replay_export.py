"""Headless replay: every frame of an episode through the streaming engine into a comparison video (drawn by
`touchanything.viz.replay_frame`), with running official metrics and engine latency, and a summary at the end."""
from __future__ import annotations

import contextlib
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import views_used
from touchanything.devices.camera_pose.estimator import STAGE
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.video_io import VideoReader
from touchanything.devices.rig.replay import ReplaySource
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.comparison_video import write_comparison_video
from touchanything.viz.frame_facts import FrameFacts, Metrics, frame_facts, metric_text
from touchanything.viz.replay_frame import ReplayFrameRenderer
from touchanything.viz.rerun_recording import RerunRecording


@dataclass
class ReplaySummary:
    """frames replayed; video: they were written into a comparison video (else only replayed: into a Rerun
    recording, or nowhere); predicted: frames with a prediction for at least one hand; no_pose: frames the engine
    answered without a valid hand pose to predict from (no contact in the metrics); metrics: cumulative
    official metrics of the last frame's facts (None without ground truth; a value None where undefined);
    latency_ms / step_ms: per-prediction latency and engine step times; hands: frames with a valid pose per hand
    [left, right]; pose_source: where the poses came from; pose_ms: the hand-pose estimator's time per frame
    (camera poses only); lamps_agree / lamps_judged: per hand [left, right], the frames whose predicted and
    measured contact lamps agree, and those where both were known (the hand predicted and measured)."""

    frames: int = 0
    video: bool = False
    predicted: int = 0
    no_pose: int = 0
    metrics: Metrics | None = None
    latency_ms: list[float] = field(default_factory=list)
    step_ms: list[float] = field(default_factory=list)
    hands: list[int] = field(default_factory=lambda: [0, 0])
    pose_source: str = ""
    pose_ms: list[float] = field(default_factory=list)
    lamps_agree: list[int] = field(default_factory=lambda: [0, 0])
    lamps_judged: list[int] = field(default_factory=lambda: [0, 0])

    def add_lamps(self, facts: FrameFacts) -> None:
        """Count one frame's contact lamps: per hand, whether they agree, where both are known."""
        for h, hand in enumerate(facts.hands):
            if hand.agree is not None:
                self.lamps_judged[h] += 1
                self.lamps_agree[h] += hand.agree

    def lamp_line(self) -> str:
        """"contact   lamps agree on 91.2 % (left 90.1 % of 280 frames, right 92.3 % of 300; where a hand was
        predicted and measured)": the overall share pools both hands' frames."""
        share = [f"{100 * n / d:.1f} %" if d else "n/a" for n, d in zip(self.lamps_agree, self.lamps_judged)]
        overall = 100 * sum(self.lamps_agree) / sum(self.lamps_judged)
        return (f"contact   lamps agree on {overall:.1f} % (left {share[0]} of {self.lamps_judged[0]} frames, right "
                f"{share[1]} of {self.lamps_judged[1]}; where a hand was predicted and measured)")

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
        done = "written" if self.video else "replayed (no video written)"
        out = [f"frames    {self.frames} {done}, {self.predicted} with a prediction{no_pose}", self.pose_line()]
        if self.metrics is None:
            out.append("metrics   n/a (the episode has no ground-truth pressure)")
        elif not self.predicted:
            out.append("metrics   n/a (no frame had a hand pose to predict from)")
        else:
            out.append("metrics   " + ", ".join(f"{k} {metric_text(v)}" for k, v in self.metrics.items()
                                                if k != "mae_left" and k != "mae_right"))
        if sum(self.lamps_judged):
            out.append(self.lamp_line())
        if self.step_ms and self.predicted:  # an engine time describes predictions: none, no figure
            step, latency = np.percentile(self.step_ms, [50, 99]), np.percentile(self.latency_ms, [50, 99])
            out.append(f"engine    {step[0]:.1f} ms per frame (p99 {step[1]:.1f}); latency p50 {latency[0]:.1f} ms, "
                       f"p99 {latency[1]:.1f} ms")
        return out


def tour_lines(summaries: list[ReplaySummary]) -> list[str]:
    """The episodes of a tour together: each official metric's mean over the episodes that define it (the
    official overall is a mean over trajectories), and the contact lamps of every episode pooled."""
    scored = [s.metrics for s in summaries if s.metrics is not None and s.predicted]
    means = {}
    for key in dict.fromkeys(k for metrics in scored for k in metrics if k not in ("mae_left", "mae_right")):
        values = [m[key] for m in scored if m.get(key) is not None]
        means[key] = float(np.mean(values)) if values else None
    out = [f"overall   {len(summaries)} episodes, {sum(s.frames for s in summaries)} frames"]
    if means:
        out.append(f"metrics   mean over the {len(scored)} episodes with a prediction and ground truth: "
                   + ", ".join(f"{k} {metric_text(v)}" for k, v in means.items()))
    pooled = ReplaySummary(lamps_agree=[sum(s.lamps_agree[h] for s in summaries) for h in range(2)],
                           lamps_judged=[sum(s.lamps_judged[h] for s in summaries) for h in range(2)])
    if sum(pooled.lamps_judged):
        out.append(pooled.lamp_line())
    return out


def replay_frames(source: ReplaySource, engine: StreamingEngine, summary: ReplaySummary,
                  progress: Callable[[ReplaySummary], None] = lambda summary: None,
                  renderer: ReplayFrameRenderer | None = None,
                  rerun: RerunRecording | None = None) -> Iterator[np.ndarray | None]:
    """Yield, for every frame of the source's episode (a ReplaySource with speed None: every frame is
    processed), its comparison frame drawn by `renderer` (None: nothing is drawn, None is yielded) and log
    it to `rerun` when given, in both the views the engine does not use (`views_used`) marked "not used";
    `progress` gets the episode's summary so far after each frame; the source is closed at the end."""
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
    used = views_used(engine.setting.views, engine.blank)
    with contextlib.closing(source):
        for snapshot in source:
            summary.add_pose(snapshot)
            for prediction in engine.step(snapshot):
                latest = prediction
                summary.latency_ms.append(prediction.latency_ms)
                if "total" in prediction.timings_ms:
                    summary.step_ms.append(prediction.timings_ms["total"])
            this = latest if latest is not None and latest.frame_index == snapshot.frame_index else None
            shown = None if this is None else this.pressure
            truth = gt[snapshot.frame_index] if gt is not None else None
            if shown is not None:
                summary.predicted += any(this.hands_predicted)
                summary.no_pose += not any(this.hands_predicted)
                if metrics is not None:
                    metrics.add(shown, truth)
            facts = frame_facts(shown, None if this is None else this.hands_predicted, truth, bend, metrics=metrics)
            summary.add_lamps(facts)
            summary.metrics = facts.cumulative
            summary.frames += 1
            if rerun is not None:
                _log_frame(rerun, episode, snapshot, truth, this if shown is not None else None, facts, used)
            progress(summary)
            spread = None if this is None else this.spread
            yield None if renderer is None else renderer.render(snapshot, truth, shown, latest, facts, used, spread)


def log_episode_videos(rerun: RerunRecording, episode: Episode, views: tuple[str, ...]) -> None:
    """The episode's own MP4 files of `views` as video assets (the other views go frame by frame)."""
    videos = {v: s.path for v, s in episode.views.items() if v in views and type(s) is VideoReader and s.path.suffix == ".mp4"}
    rerun.log_videos(videos, episode.num_frames, episode.timestamps_us / 1e6,
                     {v: (episode.views[v].width, episode.views[v].height) for v in videos})


def _log_frame(rerun: RerunRecording, episode: Episode, snapshot: Snapshot, truth: np.ndarray | None,
               prediction: Prediction | None, facts: FrameFacts, used: tuple[str, ...]) -> None:
    """One replayed frame into the recording: what the episode holds (the views the model does not use marked
    so), and the prediction of this frame, with the frame's facts."""
    time_s = float(episode.timestamps_us[snapshot.frame_index]) / 1e6
    rerun.log_observation(snapshot.frame_index, time_s, snapshot.images, snapshot.joints, snapshot.joints_valid, truth,
                          facts, snapshot.trackers, used)
    if prediction is not None:
        rerun.log_prediction(snapshot.frame_index, time_s, prediction.pressure, facts, snapshot.joints,
                             snapshot.joints_valid, truth, prediction.latency_ms, prediction.timings_ms.get("total"),
                             prediction.spread)


def export_replay(sources: list[ReplaySource], engine: StreamingEngine, out: Path | None,
                  progress: Callable[[ReplaySummary], None] = lambda summary: None, hand3d: bool = False,
                  rerun: RerunRecording | None = None, caption: tuple[str, ...] = (),
                  footers: list[str] | None = None) -> list[ReplaySummary]:
    """Write the comparison video of the sources' whole episodes, one after the other, to `out` (H.264 MP4; None:
    no video) with the 3D hands panel when `hand3d`, `caption` (what the model is, a warning) under the predicted
    maps, each episode's footer (`footers`: the engine setting's name, which episode) first in its footer, and
    the Rerun recording when given (one source); return each episode's summary (the engine starts afresh per
    episode)."""
    summaries = [ReplaySummary(video=out is not None) for _ in sources]
    footers = footers or [""] * len(sources)
    if out is None:
        for source, summary in zip(sources, summaries):
            for _ in replay_frames(source, engine, summary, progress, rerun=rerun):
                pass
        return summaries
    frames = itertools.chain.from_iterable(
        replay_frames(source, engine, summary, progress,
                      ReplayFrameRenderer(source.episode.num_frames, hand3d, caption, footer), rerun)
        for source, summary, footer in zip(sources, summaries, footers))
    write_comparison_video(out, frames)
    return summaries
