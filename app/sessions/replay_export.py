"""Headless replay: every frame of an episode through the streaming engine into a comparison video (drawn by
`touchanything.viz.replay_frame`), with running official metrics and engine latency, and a summary at the end."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from touchanything.devices.episodes.episode import Episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.comparison_video import write_comparison_video
from touchanything.viz.replay_frame import ReplayFrameRenderer, metric_text


@dataclass
class ReplaySummary:
    """frames written; predicted: frames with a prediction; metrics: cumulative official metrics (None
    without ground truth); latency_ms / step_ms: per-prediction latency and engine step times."""

    frames: int = 0
    predicted: int = 0
    metrics: dict[str, float] | None = None
    latency_ms: list[float] = field(default_factory=list)
    step_ms: list[float] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = [f"frames    {self.frames} written, {self.predicted} with a prediction"]
        if self.metrics is None:
            out.append("metrics   n/a (the episode has no ground-truth pressure)")
        else:
            out.append("metrics   " + ", ".join(f"{k} {metric_text(v)}" for k, v in self.metrics.items()
                                                if k != "mae_left" and k != "mae_right"))
        if self.step_ms:
            step, latency = np.percentile(self.step_ms, [50, 99]), np.percentile(self.latency_ms, [50, 99])
            out.append(f"engine    {step[0]:.1f} ms per frame (p99 {step[1]:.1f}); latency p50 {latency[0]:.1f} ms, "
                       f"p99 {latency[1]:.1f} ms")
        return out


def replay_frames(episode: Episode, engine: StreamingEngine, views: tuple[str, ...], summary: ReplaySummary,
                  progress: Callable[[int], None] = lambda frame: None) -> Iterator[np.ndarray]:
    """Yield comparison frames for every frame of the episode (replay mode: every frame is processed)."""
    gt = None
    if episode.pressure is not None:
        gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
    bend = TactileLayout.default().bend
    metrics = RunningMetrics(bend) if gt is not None else None
    renderer = ReplayFrameRenderer(episode.num_frames, bend)
    engine.reset()
    latest: Prediction | None = None
    for snapshot in ReplaySource(episode, ReplayConfig(speed=None, views=views)):
        for prediction in engine.step(snapshot):
            latest = prediction
            summary.latency_ms.append(prediction.latency_ms)
            if "total" in prediction.timings_ms:
                summary.step_ms.append(prediction.timings_ms["total"])
        shown = latest.pressure if latest is not None and latest.frame_index == snapshot.frame_index else None
        truth = gt[snapshot.frame_index] if gt is not None else None
        if shown is not None:
            summary.predicted += 1
            if metrics is not None:
                metrics.add(shown, truth)
        summary.frames += 1
        progress(snapshot.frame_index)
        yield renderer.render(snapshot, truth, shown, latest, metrics)
    summary.metrics = metrics.cumulative() if metrics is not None else None


def export_replay(episode: Episode, engine: StreamingEngine, views: tuple[str, ...], out: Path,
                  progress: Callable[[int], None] = lambda frame: None) -> ReplaySummary:
    """Write the comparison video of the whole episode to `out` (H.264 MP4); return the summary."""
    summary = ReplaySummary()
    write_comparison_video(out, replay_frames(episode, engine, views, summary, progress))
    return summary
