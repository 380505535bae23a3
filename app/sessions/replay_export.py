"""Headless replay: every frame of an episode through the streaming engine into a comparison video (the
head camera with the hand skeletons and predicted pressure on their joints), with running official metrics
and engine latency in the footer, and a summary at the end."""
from __future__ import annotations

import math
from collections.abc import Callable
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
from touchanything.viz.comparison_video import STRIP_HEIGHT, comparison_frame, write_comparison_video
from touchanything.viz.contact import contact_badges, hand_contact
from touchanything.viz.hand_projection import draw_hands
from touchanything.viz.line_plot import LATENCY_PLOT_MS, PLOT_SAMPLES, line_plot


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
            out.append("metrics   " + ", ".join(f"{k} {_value(v)}" for k, v in self.metrics.items() if k != "mae_left"
                                                and k != "mae_right"))
        if self.step_ms:
            step, latency = np.percentile(self.step_ms, [50, 99]), np.percentile(self.latency_ms, [50, 99])
            out.append(f"engine    {step[0]:.1f} ms per frame (p99 {step[1]:.1f}); latency p50 {latency[0]:.1f} ms, "
                       f"p99 {latency[1]:.1f} ms")
        return out


def _value(value: float) -> str:
    return "n/a" if math.isnan(value) else f"{value:.3f}"


def _footer(snapshot_index: int, total: int, prediction: Prediction | None, metrics: RunningMetrics | None) -> str:
    parts = [f"Frame {snapshot_index:04d}/{total}"]
    if prediction is not None:
        parts.append(f"{prediction.status} | {'+'.join(prediction.views_used)} | {prediction.timings_ms.get('total', 0):.0f} ms")
    if metrics is not None:
        rolling, total_metrics = metrics.rolling(), metrics.cumulative()
        parts.append(f"V-IoU {_value(rolling['volumetric_iou'])} (3 s) {_value(total_metrics['volumetric_iou'])} (all)")
        parts.append(f"C-IoU {_value(total_metrics['contact_iou'])}")
    return "  |  ".join(parts)


class _History:
    """The recent per-frame series drawn in the bottom strip."""

    def __init__(self) -> None:
        self.viou: list[float] = []
        self.ciou: list[float] = []
        self.step_ms: list[float] = []

    def add(self, metrics: RunningMetrics | None, prediction: Prediction | None) -> None:
        rolling = metrics.rolling() if metrics is not None else None
        self.viou.append(rolling["volumetric_iou"] if rolling else math.nan)
        self.ciou.append(rolling["contact_iou"] if rolling else math.nan)
        self.step_ms.append(prediction.timings_ms.get("total", math.nan) if prediction is not None else math.nan)
        for series in (self.viou, self.ciou, self.step_ms):
            del series[:-PLOT_SAMPLES]

    def strip(self, pred: np.ndarray | None, truth: np.ndarray | None, bend: np.ndarray) -> np.ndarray:
        """(150, 1440, 3): rolling metrics | engine time per frame | contact lamps."""
        title = "metrics, rolling 3 s" if truth is not None else "metrics: n/a (no ground truth)"
        return np.concatenate([
            line_plot({"V-IoU": self.viou, "C-IoU": self.ciou}, 480, STRIP_HEIGHT, 1.0, title, PLOT_SAMPLES),
            line_plot({"engine": self.step_ms}, 480, STRIP_HEIGHT, LATENCY_PLOT_MS, "engine time per frame",
                      PLOT_SAMPLES, " ms"),
            contact_badges(hand_contact(pred, bend), hand_contact(truth, bend), 480, STRIP_HEIGHT)], axis=1)


def replay_frames(episode: Episode, engine: StreamingEngine, views: tuple[str, ...], summary: ReplaySummary,
                  progress: Callable[[int], None] = lambda frame: None):
    """Yield comparison frames for every frame of the episode (replay mode: every frame is processed)."""
    gt = None
    if episode.pressure is not None:
        gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
    bend = TactileLayout.default().bend
    metrics = RunningMetrics(bend) if gt is not None else None
    history = _History()
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
        history.add(metrics, latest)
        images = dict(snapshot.images)
        if "ego" in images:
            images["ego"] = draw_hands(images["ego"], snapshot.joints, snapshot.joints_valid, shown)
        yield comparison_frame(images, truth, shown, _footer(snapshot.frame_index, episode.num_frames, latest, metrics),
                               history.strip(shown, truth, bend))
    summary.metrics = metrics.cumulative() if metrics is not None else None


def export_replay(episode: Episode, engine: StreamingEngine, views: tuple[str, ...], out: Path,
                  progress: Callable[[int], None] = lambda frame: None) -> ReplaySummary:
    """Write the comparison video of the whole episode to `out` (H.264 MP4); return the summary."""
    summary = ReplaySummary()
    write_comparison_video(out, replay_frames(episode, engine, views, summary, progress))
    return summary
