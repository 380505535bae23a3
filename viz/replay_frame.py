"""One frame of the replay comparison video: the cameras (the head camera with the hand skeletons and the
shown pressure on their joints), the measured | predicted [| members' spread] | difference maps, a bottom strip (rolling metrics,
engine time per frame, contact lamps) and a footer with the engine setting, the frame, where the pose comes from,
the prediction's status, the views it used (their view-set id) and the metrics. What the maps, the lamps, the
plots and the footer say of the frame is its `FrameFacts` (`viz.frame_facts`)."""
from __future__ import annotations

import math

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.view_sets import view_set_name
from touchanything.inference.engine.prediction import Prediction
from touchanything.viz.comparison_video import STRIP_HEIGHT, comparison_frame
from touchanything.viz.contact import contact_badges
from touchanything.viz.frame_facts import FrameFacts, metric_text
from touchanything.viz.hand3d_panel import hand3d_panel
from touchanything.viz.hand_projection import draw_hands, pose_label
from touchanything.viz.line_plot import LATENCY_PLOT_MS, PLOT_SAMPLES, line_plot
from touchanything.viz.pressure_panel import unposed_as_nan


def footer_text(snapshot: Snapshot, total: int, prediction: Prediction | None, facts: FrameFacts | None,
                setting: str = "") -> str:
    """`setting` (the engine setting's name, `bench_setting`) first when given; the metrics are the frame's
    `facts`' (none without them or without ground truth)."""
    parts = [setting] if setting else []
    parts += [f"Frame {snapshot.frame_index:04d}/{total}", pose_label(snapshot)]
    if prediction is not None:
        views = view_set_name(prediction.views_used) or "no view"
        parts.append(f"{prediction.status} | views {views} | {prediction.timings_ms.get('total', 0):.0f} ms")
    if facts is not None and facts.rolling is not None and facts.cumulative is not None:
        rolling, cumulative = facts.rolling, facts.cumulative
        parts.append(f"V-IoU {metric_text(rolling['volumetric_iou'])} (3 s) {metric_text(cumulative['volumetric_iou'])} (all)")
        parts.append(f"C-IoU {metric_text(cumulative['contact_iou'])}")
    return "  |  ".join(parts)


class ReplayFrameRenderer:
    """Renders the frames of one episode, in order: keeps the recent per-frame series the bottom strip plots.
    `hand3d`: add the panel of the pressure painted on the 3D hands (`viz.hand3d_panel`); `caption`: lines
    under the predicted maps (what the model is); `setting`: the engine setting's name, first in the footer."""

    def __init__(self, total_frames: int, hand3d: bool = False, caption: tuple[str, ...] = (), setting: str = "") -> None:
        self.total_frames = total_frames
        self.caption = caption
        self.setting = setting
        self.hand3d = hand3d
        self.viou: list[float] = []
        self.ciou: list[float] = []
        self.step_ms: list[float] = []

    def render(self, snapshot: Snapshot, truth: np.ndarray | None, shown: np.ndarray | None,
               latest: Prediction | None, facts: FrameFacts, used: tuple[str, ...] = VIEW_NAMES,
               spread: np.ndarray | None = None) -> np.ndarray:
        """The comparison frame of `snapshot`: `shown` is the prediction of this very frame (None when there
        is none), `latest` the newest prediction so far, `facts` this frame's (`viz.frame_facts`): which hands
        the maps show, the contact lamps and the metrics of the plots and the footer; `used`: the views the
        model takes anything from (the others are marked "not used"); `spread`: an ensemble's spread of this
        frame (`Prediction.spread`), drawn beside the predicted maps (None: a single model, no panel)."""
        self._add(facts, latest)
        images = dict(snapshot.images)
        if "ego" in images:
            images["ego"] = draw_hands(images["ego"], snapshot.joints, snapshot.joints_valid, shown)
        footer = footer_text(snapshot, self.total_frames, latest, facts, self.setting)
        hands = hand3d_panel(snapshot.joints, snapshot.joints_valid, truth, shown) if self.hand3d else None
        maps = None if shown is None else unposed_as_nan(shown, facts.posed)
        spread = None if spread is None or shown is None else unposed_as_nan(spread, facts.posed)
        return comparison_frame(images, truth, maps, footer, self._strip(facts), hands, self.caption, used, spread)

    def _add(self, facts: FrameFacts, prediction: Prediction | None) -> None:
        rolling = facts.rolling or {}
        for series, key in ((self.viou, "volumetric_iou"), (self.ciou, "contact_iou")):
            value = rolling.get(key)
            series.append(math.nan if value is None else value)
        self.step_ms.append(prediction.timings_ms.get("total", math.nan) if prediction is not None else math.nan)
        for series in (self.viou, self.ciou, self.step_ms):
            del series[:-PLOT_SAMPLES]

    def _strip(self, facts: FrameFacts) -> np.ndarray:
        """(150, 1440, 3): rolling metrics | engine time per frame | contact lamps."""
        title = "metrics, rolling 3 s" if facts.rolling is not None else "metrics: n/a (no ground truth)"
        return np.concatenate([
            line_plot({"V-IoU": self.viou, "C-IoU": self.ciou}, 480, STRIP_HEIGHT, 1.0, title, PLOT_SAMPLES),
            line_plot({"engine": self.step_ms}, 480, STRIP_HEIGHT, LATENCY_PLOT_MS, "engine time per frame",
                      PLOT_SAMPLES, " ms"),
            contact_badges(facts, 480, STRIP_HEIGHT)], axis=1)
