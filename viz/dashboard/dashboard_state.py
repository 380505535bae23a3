"""What the dashboard shows and what it may ask for: the records a session publishes (latest values, read
by the render loop without waiting) and the control interface a replay or live session implements."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.evaluation.atlas import AtlasRow
from touchanything.viz.frame_facts import FrameFacts, Metrics
from touchanything.viz.model_accuracy import ModelAccuracy


@dataclass(frozen=True)
class SourceStatus:
    """One row of the device table. rate_hz: measured sample rate; age_ms: now − capture time of the
    latest sample (None: no sample yet); drops: samples lost or replaced before use; in_scene: False for a
    source the scene or episode does not have at all (shown as such, not as a failure)."""

    name: str
    connected: bool
    rate_hz: float | None = None
    age_ms: float | None = None
    drops: int = 0
    detail: str = ""
    in_scene: bool = True


@dataclass(frozen=True)
class Playback:
    """Replay transport: the next frame to play, the episode length, paused, real-time factor."""

    position: int
    frames: int
    paused: bool
    speed: float


@dataclass(frozen=True)
class SessionState:
    """One consistent picture, published by the session and read by the render loop.

    snapshot: the camera frame and prediction: the prediction the session last published together (one record,
    swapped in one step: every panel draws from it); the prediction is None before the first, and after the
    figures restarted — a seek, a switch — until the engine predicts again; truth: the (2, 21, 21)
    measured pressure of the prediction's frame (without a prediction: of the frame shown when the figures
    restarted; None without a glove / ground truth); facts: the prediction's `FrameFacts` (posed and measured
    hands, contact lamps, the official metrics as they stood after it: what every panel shows of it);
    metric_frames: the frames the running metrics count; views_used: the views the running model takes
    anything from (`view_sets.views_used`: none for a pose-only model, none without a model); history: recent
    series by name (volumetric_iou, contact_iou rolling; latency_ms), oldest first; stage_ms: mean
    engine stage times over recent steps; engine_fps: predictions per second; sources: device rows;
    playback: None in live mode; model: the running model and tier with its one held-out accuracy; accuracy: that
    accuracy and its source (`model_accuracy`: the model line's and the atlas line's); message: the latest notice;
    setting: the running engine setting's name (`nano/onnx-int8/all`); step_p99_ms: p99 of the engine's per-frame
    step time over its recent predictions (None before enough of them); steps_timed: how many step times that
    window holds (predictions with pressure since the setting last restarted, at most its length); atlas: the
    speed/accuracy atlas's settings of the models here (empty, with `atlas_note` saying why, when there is none);
    members: the running engine's
    ensemble members (1 for a single model and without a model: its predictions have no spread); news: how many
    records (snapshot with prediction) the session has published, this one included (`wait_for_news`)."""

    snapshot: Snapshot | None = None
    prediction: Prediction | None = None
    truth: np.ndarray | None = None
    facts: FrameFacts | None = None
    metric_frames: int = 0
    views_used: tuple[str, ...] = VIEW_NAMES
    history: dict[str, np.ndarray] = field(default_factory=dict)
    stage_ms: dict[str, float] = field(default_factory=dict)
    engine_fps: float = 0.0
    sources: tuple[SourceStatus, ...] = ()
    playback: Playback | None = None
    model: str = ""
    accuracy: ModelAccuracy = ModelAccuracy(caption="")
    message: str = ""
    recording: str | None = None
    setting: str = ""
    step_p99_ms: float | None = None
    steps_timed: int = 0
    atlas: tuple[AtlasRow, ...] = ()
    atlas_note: str = ""
    members: int = 1
    news: int = 0

    @property
    def rolling(self) -> dict[str, float] | None:
        """The facts' official metrics over the last 3 s, NaN where undefined (None without ground truth)."""
        return _with_nan(None if self.facts is None else self.facts.rolling)

    @property
    def cumulative(self) -> dict[str, float] | None:
        """The facts' official metrics since the start, NaN where undefined (None without ground truth)."""
        return _with_nan(None if self.facts is None else self.facts.cumulative)


def _with_nan(metrics: Metrics | None) -> dict[str, float] | None:
    return None if metrics is None else {key: math.nan if value is None else value for key, value in metrics.items()}


class DashboardSession(Protocol):
    """Controls are called from the GUI thread and must return at once (slow work goes to a thread)."""

    views: tuple[str, ...]
    threshold: float

    def state(self) -> SessionState: ...

    def wait_for_news(self, seen: int, timeout: float) -> int:
        """Block until more than `seen` records are published or `timeout` s passed; how many are now."""

    def play(self) -> None: ...

    def pause(self) -> None: ...

    def step(self) -> None: ...

    def seek(self, frame: int) -> None: ...

    def set_speed(self, speed: float) -> None: ...

    def set_views(self, views: tuple[str, ...]) -> None: ...

    def set_threshold(self, threshold: float) -> None: ...

    def models(self) -> tuple[str, ...]: ...

    def tiers(self) -> tuple[str, ...]: ...

    def current_model(self) -> tuple[str, str]: ...

    def set_model(self, model: str, tier: str) -> None: ...

    def current_rate(self) -> int: ...

    def set_rate(self, every: int) -> None: ...

    def toggle_recording(self) -> None: ...

    def close(self) -> None: ...
