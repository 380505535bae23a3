"""One frame of the replay comparison video: the cameras (the head camera with the hand skeletons and the
shown pressure on their joints), ground truth | prediction | error maps, a bottom strip (rolling metrics,
engine time per frame, contact lamps) and a footer with the engine setting, the frame, where the pose comes from,
the prediction's status and the metrics."""
from __future__ import annotations

import math

import numpy as np

from touchanything.devices.snapshot import Snapshot
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.comparison_video import STRIP_HEIGHT, comparison_frame
from touchanything.viz.contact import contact_badges, hand_contact
from touchanything.viz.hand3d_panel import hand3d_panel
from touchanything.viz.hand_projection import draw_hands, pose_label
from touchanything.viz.line_plot import LATENCY_PLOT_MS, PLOT_SAMPLES, line_plot
from touchanything.viz.pressure_panel import unposed_as_nan


def metric_text(value: float) -> str:
    """A metric with three decimals, or n/a when undefined (NaN)."""
    return "n/a" if math.isnan(value) else f"{value:.3f}"


def footer_text(snapshot: Snapshot, total: int, prediction: Prediction | None, metrics: RunningMetrics | None,
                setting: str = "") -> str:
    """`setting` (the engine setting's name, `bench_setting`) first when given."""
    parts = [setting] if setting else []
    parts += [f"Frame {snapshot.frame_index:04d}/{total}", pose_label(snapshot)]
    if prediction is not None:
        parts.append(f"{prediction.status} | {'+'.join(prediction.views_used)} | {prediction.timings_ms.get('total', 0):.0f} ms")
    if metrics is not None:
        rolling, total_metrics = metrics.rolling(), metrics.cumulative()
        parts.append(f"V-IoU {metric_text(rolling['volumetric_iou'])} (3 s) {metric_text(total_metrics['volumetric_iou'])} (all)")
        parts.append(f"C-IoU {metric_text(total_metrics['contact_iou'])}")
    return "  |  ".join(parts)


class ReplayFrameRenderer:
    """Renders the frames of one episode, in order: keeps the recent per-frame series the bottom strip plots.
    `hand3d`: add the panel of the pressure painted on the 3D hands (`viz.hand3d_panel`); `caption`: lines
    under the predicted maps (what the model is); `setting`: the engine setting's name, first in the footer."""

    def __init__(self, total_frames: int, bend: np.ndarray, hand3d: bool = False, caption: tuple[str, ...] = (),
                 setting: str = "") -> None:
        self.total_frames = total_frames
        self.caption = caption
        self.setting = setting
        self.bend = bend
        self.hand3d = hand3d
        self.viou: list[float] = []
        self.ciou: list[float] = []
        self.step_ms: list[float] = []

    def render(self, snapshot: Snapshot, truth: np.ndarray | None, shown: np.ndarray | None,
               latest: Prediction | None, metrics: RunningMetrics | None) -> np.ndarray:
        """The comparison frame of `snapshot`: `shown` is the prediction of this very frame (None when there
        is none), `latest` the newest prediction so far, `metrics` the running metrics (None without truth)."""
        self._add(metrics, latest)
        images = dict(snapshot.images)
        if "ego" in images:
            images["ego"] = draw_hands(images["ego"], snapshot.joints, snapshot.joints_valid, shown)
        footer = footer_text(snapshot, self.total_frames, latest, metrics, self.setting)
        hands = hand3d_panel(snapshot.joints, snapshot.joints_valid, truth, shown) if self.hand3d else None
        maps = None if shown is None or latest is None else unposed_as_nan(shown, latest.hands_predicted)
        return comparison_frame(images, truth, maps, footer, self._strip(shown, truth), hands, self.caption)

    def _add(self, metrics: RunningMetrics | None, prediction: Prediction | None) -> None:
        rolling = metrics.rolling() if metrics is not None else None
        self.viou.append(rolling["volumetric_iou"] if rolling else math.nan)
        self.ciou.append(rolling["contact_iou"] if rolling else math.nan)
        self.step_ms.append(prediction.timings_ms.get("total", math.nan) if prediction is not None else math.nan)
        for series in (self.viou, self.ciou, self.step_ms):
            del series[:-PLOT_SAMPLES]

    def _strip(self, pred: np.ndarray | None, truth: np.ndarray | None) -> np.ndarray:
        """(150, 1440, 3): rolling metrics | engine time per frame | contact lamps."""
        title = "metrics, rolling 3 s" if truth is not None else "metrics: n/a (no ground truth)"
        return np.concatenate([
            line_plot({"V-IoU": self.viou, "C-IoU": self.ciou}, 480, STRIP_HEIGHT, 1.0, title, PLOT_SAMPLES),
            line_plot({"engine": self.step_ms}, 480, STRIP_HEIGHT, LATENCY_PLOT_MS, "engine time per frame",
                      PLOT_SAMPLES, " ms"),
            contact_badges(hand_contact(pred, self.bend), hand_contact(truth, self.bend), 480, STRIP_HEIGHT)], axis=1)
