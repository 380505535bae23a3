"""What replay and live sessions share: snapshots handed to the live engine (latest wins), predictions
paired with the measured pressure of their frame, running official metrics, history for the plots,
per-stage timings, and the model / view / threshold switches (never blocking the caller).

Where the figures restart (docs/dashboard.md lists it for the user): a seek, an episode's start (loop, tour)
and every switch of the setting — model, tier, prediction rate, views — forget the engine's window, the
shown prediction (none until the engine predicts again; the shown frame's measurement stays), the running
metrics and the plots' history; a setting switch also forgets the engine's step and stage times (they
describe the setting). A new contact threshold restarts the metrics and their plot lines and decides the
shown prediction's facts again (same model, same frame).

What the dashboard draws is one published record, the newest snapshot with the newest prediction, swapped in one
step under the lock (`state` reads only it): a prediction publishes at once; a snapshot handed to the engine
waits for a prediction (at most PREDICTION_WAIT_S, so that a slow engine never holds the cameras back), one that
is not (no engine, skipped) publishes at once. So a 30 fps replay publishes about 30 records a second, not one for
its frame and another for its prediction, and `wait_for_news` lets the display sleep until the next."""
from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

import numpy as np

from touchanything.app.sessions.budget_watch import BudgetWatch
from touchanything.app.sessions.bundled import ATLAS_FILE, bundled_models
from touchanything.app.sessions.engine_choice import (
    CPU_TIERS,
    ModelChoice,
    build_engine,
    illustrative_note,
    model_label,
    tiers_for,
)
from touchanything.app.sessions.published_record import PublishedRecord
from touchanything.app.sessions.rerun_sink import RerunSink
from touchanything.app.sessions.setting_choice import display_atlas, running_accuracy
from touchanything.core.errors import UserError
from touchanything.core.snapshot import POSE_FROM_CAMERA, VIEW_NAMES, Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import views_used
from touchanything.devices.rate_meter import RateMeter, StageMeans
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.live_engine import LiveEngine
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import CONTACT_THRESHOLD
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.dashboard.dashboard_state import Playback, SessionState, SourceStatus
from touchanything.viz.frame_facts import FrameFacts, frame_facts
from touchanything.viz.line_plot import PLOT_SAMPLES
from touchanything.viz.model_accuracy import ModelAccuracy

RECENT_FRAMES = 64
"""Snapshots kept to pair late predictions with their frame's measured pressure."""
STEP_WINDOW = 100
"""Engine step times kept for the live p99 the atlas panel places the running setting at."""
MIN_STEPS = 10
PredictionRecord = tuple[Prediction | None, np.ndarray | None, FrameFacts]
"""A prediction (None: restarted figures), the measured pressure of its frame and their facts."""
PREDICTION_WAIT_S = 0.025
"""How long a snapshot handed to the engine waits for a prediction before it is published on its own (a frame
period at 40 fps: the engine predicts a 30 fps replay's frame well within it when it keeps up)."""


class EngineSession:
    """Subclasses feed `submit(snapshot)` from their source thread and provide `truth_of`, `playback`
    and `source_rows`. `engine` None (its model failed to load) still shows cameras and measurements.
    `rerun`, when set before `start`, gets every snapshot and prediction (and is closed after the engine).
    The dashboard's atlas panel shows the committed atlas unless `use_atlas` names another."""

    def __init__(self, engine: StreamingEngine | None, choice: ModelChoice, message: str = "") -> None:
        self.views = tuple(VIEW_NAMES)
        self.threshold = CONTACT_THRESHOLD
        self.choice = choice
        self.bend = TactileLayout.default().bend
        self.metrics = RunningMetrics(self.bend)
        self._truth_seen = False
        self._lock = threading.Lock()
        self._recent: dict[int, tuple[Snapshot, np.ndarray | None]] = {}
        self._sought: int | None = None
        """After a seek, the frame the source was moved to: a snapshot the source took before the seek (another
        frame, delivered late) is dropped until that frame comes, so that it never counts in the new metrics."""
        self._snapshot: Snapshot | None = None
        self._prediction: PredictionRecord | None = None
        """The newest prediction (None after a restart, until the engine predicts again), its frame's truth, facts."""
        self._shown = PublishedRecord(self._lock)
        """What the dashboard shows: (snapshot, prediction record) as last published (see the module)."""
        self._engine = engine
        """The engine whose predictions count: one still in flight from an engine switched away is dropped."""
        self._pose_only = engine is not None and engine.blank
        self._history = {name: deque(maxlen=PLOT_SAMPLES) for name in ("volumetric_iou", "contact_iou", "latency_ms")}
        self._stages = StageMeans()
        self._steps: deque[float] = deque(maxlen=STEP_WINDOW)
        self.atlas, self.atlas_note = display_atlas(ATLAS_FILE)
        self.frames, self._predictions = RateMeter(), RateMeter()
        self.message = message
        self.budget: BudgetWatch | None = None
        """The budget the running setting was chosen for (`--setting auto`); an overrun becomes the message, once."""
        self._loading = False
        self._model = model_label(choice, engine) if engine is not None else "no model"
        self._accuracy: tuple[tuple, ModelAccuracy] = ((), ModelAccuracy())
        """The running setting's accuracy and what it was worked out for (`_running_accuracy`)."""
        self._camera_note = illustrative_note(choice, camera_pose=True)
        self.live = LiveEngine(engine, on_prediction=self._on_prediction) if engine is not None else None
        self.rerun: RerunSink | None = None

    def use_atlas(self, atlas: Path) -> None:
        """Show the settings of `atlas` (a `bench` engine.json) in the dashboard's atlas panel."""
        self.atlas, self.atlas_note = display_atlas(atlas)

    def truth_of(self, snapshot: Snapshot) -> np.ndarray | None:
        """(2, 21, 21) measured pressure of the snapshot's frame, or None."""
        raise NotImplementedError

    def playback(self) -> Playback | None:
        return None

    def source_rows(self, snapshot: Snapshot | None) -> list[SourceStatus]:
        raise NotImplementedError

    def start_engine(self) -> None:
        if self.live is not None:
            self.live.start()

    def stop_engine(self) -> None:
        """An engine error is reported in the message, not raised (the session is ending)."""
        if self.live is not None:
            try:
                self.live.stop()
            except Exception as exc:  # shown to the user; the session ends either way
                self.message = f"engine stopped with an error: {exc}"
        if self.rerun is not None:
            self.rerun.close()

    def submit(self, snapshot: Snapshot, predict: bool = True) -> None:
        """Source thread: show the snapshot and hand it (with only the views switched on) to the engine;
        `predict` False: the engine skips it (counted as dropped). After a seek, snapshots of other frames than
        the sought one are dropped until it comes."""
        with self._lock:
            if self._sought is not None and snapshot.frame_index != self._sought:
                return
            self._sought = None
        truth = self.truth_of(snapshot)
        with self._lock:
            self._snapshot = snapshot
            self._recent[snapshot.frame_index] = (snapshot, truth)
            while len(self._recent) > RECENT_FRAMES:
                self._recent.pop(next(iter(self._recent)))
            if self.live is not None and predict:
                self._shown.hold(PREDICTION_WAIT_S)
            else:
                self._publish()
        self.frames.tick()
        self._stages.add(snapshot.stage_ms)
        if self.rerun is not None:
            self.rerun.observe(snapshot, truth, self.threshold, self._views_used())
        if self.live is not None and not predict:
            self.live.skip()
        elif self.live is not None:
            images = {v: im for v, im in snapshot.images.items() if v in self.views}
            self.live.submit(dataclasses.replace(snapshot, images=images))

    def _on_prediction(self, prediction: Prediction) -> None:
        """Engine thread: keep the prediction with its facts (decided once, here, for every panel and the Rerun
        recording), feed the metrics (frames submitted before a restart, and an old engine's predictions, are
        ignored)."""
        with self._lock:
            if prediction.frame_index not in self._recent or self.live.engine is not self._engine:
                return
            snapshot, truth = self._recent[prediction.frame_index]
            if prediction.pressure is not None:
                self._time(prediction)
            if truth is not None and prediction.pressure is not None:
                self._truth_seen = True
                self.metrics.add(prediction.pressure, truth)
            facts = self._facts(prediction, truth)
            if truth is not None and prediction.pressure is not None:
                for key in ("volumetric_iou", "contact_iou"):
                    self._history[key].append(np.nan if facts.rolling[key] is None else facts.rolling[key])
            self._prediction = (prediction, truth, facts)
            self._publish()
            if self.rerun is not None:
                self.rerun.predicted(prediction, snapshot, truth, facts)

    def _time(self, prediction: Prediction) -> None:
        """Count a prediction with pressure in the engine's rate, stage times, step times and latency (one without
        pressure — no head camera — predicted nothing: it is timed nowhere; the lock is held)."""
        self._predictions.tick()
        self._stages.add(prediction.timings_ms)
        if "total" in prediction.timings_ms:
            self._steps.append(prediction.timings_ms["total"])
        self._history["latency_ms"].append(prediction.latency_ms)

    def _facts(self, prediction: Prediction | None, truth: np.ndarray | None) -> FrameFacts:
        """The facts of `prediction` (None: of its frame's measurement alone) at the session's threshold, with the
        metrics as they stand (none before any ground truth)."""
        if prediction is None:
            return frame_facts(None, None, truth, self.bend, self.threshold)
        return frame_facts(prediction.pressure, prediction.hands_predicted, truth, self.bend, self.threshold,
                           self.metrics if self._truth_seen else None)

    def restart(self, sought: int | None = None) -> None:
        """Start the figures afresh (at an episode's start; before a seek to frame `sought`, whose snapshot is
        the next one taken): see the module."""
        self._restart(setting=False, sought=sought)

    def _restart(self, setting: bool, change: Callable[[], None] = lambda: None, sought: int | None = None) -> None:
        """Apply `change` (to the setting) and restart the figures in one step under the lock, so that no state
        shows the one without the other; `setting`: also forget the step and stage times. The engine's window
        is reset before its next step."""
        with self._lock:
            change()
            self._sought = sought
            shown = self._recent.get(self._snapshot.frame_index) if self._snapshot is not None else None
            truth = shown[1] if shown is not None and shown[0] is self._snapshot else None
            self._recent.clear()
            self.metrics.reset()
            self._truth_seen = False
            for values in self._history.values():
                values.clear()
            self._prediction = None if truth is None else (None, truth, self._facts(None, truth))
            if setting:
                self._steps.clear()
                self._stages = StageMeans()
                self._predictions.reset()
            self._publish()
        if self.live is not None:
            self.live.call(lambda: self.live.engine.reset())

    def _publish(self) -> None:
        """Make the newest snapshot and prediction the shown record, in one step (the lock is held)."""
        self._shown.publish((self._snapshot, self._prediction))

    def _publish_overdue(self) -> None:
        """Publish a snapshot that waited PREDICTION_WAIT_S for a prediction without one (the lock is held)."""
        if self._shown.overdue():
            self._publish()

    def wait_for_news(self, seen: int, timeout: float) -> int:
        """Block until more than `seen` records were published (`SessionState.news`), or `timeout` s passed;
        the number published now."""
        return self._shown.wait(seen, timeout, self._publish_overdue)

    def state(self) -> SessionState:
        """The session now, its snapshot and prediction the published record. Paused, nothing runs: the engine's
        rate reads 0 and its row says "paused" (not the rate it had)."""
        with self._lock:
            self._publish_overdue()
            snapshot, record = self._shown.shown
            prediction, truth, facts = record or (None, None, None)
            playback = self.playback()
            paused = playback is not None and playback.paused
            rows = self.source_rows(snapshot)
            accuracy = self._running_accuracy() if self.live is not None else ModelAccuracy(caption="")
            if self.live is not None:
                stats = self.live.stats
                detail = "loading a model…" if self._loading else f"{stats.processed} processed, {self.live.engine.runtime.capture}"
                detail = f"paused, {detail}" if paused else detail
                rows.append(SourceStatus("engine", self.live.error is None, None if paused else self._predictions.rate(),
                                         None, stats.dropped, detail if self.live.error is None else f"error: {self.live.error}"))
            return SessionState(
                snapshot=snapshot, prediction=prediction, truth=truth, facts=facts, metric_frames=self.metrics.frames,
                views_used=self._views_used(),
                history={name: np.array(values, np.float64) for name, values in self._history.items()},
                stage_ms=self._stages.means(), engine_fps=0.0 if paused else self._predictions.rate(), sources=tuple(rows),
                playback=playback, model=self._model_line(snapshot, accuracy.line), accuracy=accuracy,
                message=self.message, recording=self.recording_status(), setting=self._setting_name(),
                step_p99_ms=self._step_p99(), steps_timed=len(self._steps),
                atlas=self.atlas, atlas_note=self.atlas_note,
                members=self.choice.setting.members if self.live is not None else 1, news=self._shown.count)

    def _step_p99(self) -> float | None:
        """p99 of the engine's recent step times (None: too few yet); an overrun of the budget is said once."""
        p99 = float(np.percentile(self._steps, 99)) if len(self._steps) >= MIN_STEPS else None
        if self.budget is not None and (line := self.budget.over(p99)):
            self.message = line
        return p99

    def _setting_name(self) -> str:
        """The running setting's name with the views switched on ("" without a model or without the head camera:
        then nothing is predicted)."""
        if self.live is None or "ego" not in self.views:
            return ""
        return self._running_setting().name()

    def _running_setting(self) -> EngineSetting:
        """The setting that runs: the choice's with the views switched on (without the head camera, whose
        accuracy the model's line gives: the choice's)."""
        return self.choice.with_setting(views=self.views).setting if "ego" in self.views else self.choice.setting

    def _running_accuracy(self) -> ModelAccuracy:
        """The running setting's one accuracy (`model_accuracy`: the atlas's once this model's weights are in it,
        else its card's), worked out again only when the setting, the model or the atlas changed."""
        key = (self._running_setting(), self.choice.checkpoint, self.atlas)
        if self._accuracy[0] != key:
            self._accuracy = (key, running_accuracy(dataclasses.replace(self.choice, setting=key[0]), self.atlas))
        return self._accuracy[1]

    def _views_used(self) -> tuple[str, ...]:
        """The views the running model takes anything from (none without a model)."""
        return views_used(self.views, self._pose_only) if self.live is not None else ()

    def _model_line(self, snapshot: Snapshot | None, accuracy: str) -> str:
        """The model's title with its one `accuracy` line, and the illustrative-only note while the poses come from
        the camera."""
        line = f"{self._model}; {accuracy}" if accuracy and self.live else self._model
        camera = snapshot is not None and snapshot.pose_source == POSE_FROM_CAMERA
        return f"{line} — {self._camera_note}" if camera and self._camera_note and self.live else line

    def recording_status(self) -> str | None:
        return None

    @staticmethod
    def age_ms(t_us: int | None) -> float | None:
        return None if t_us is None else time.monotonic() * 1e3 - t_us / 1e3

    def set_views(self, views: tuple[str, ...]) -> None:
        """Views the model may use from the next frame on ("ego" off: no prediction, with the reason); a change
        restarts the figures."""
        chosen = tuple(v for v in VIEW_NAMES if v in views)
        if chosen != self.views:
            self._restart(setting=True, change=lambda: setattr(self, "views", chosen))

    def set_threshold(self, threshold: float) -> None:
        """Contact threshold for the metrics and indicators (official 0.1); the metrics and their history
        restart, and the shown prediction's facts are decided again at the new threshold."""
        if not 0.0 < threshold < 1.0:
            raise UserError(f"contact threshold must lie in (0, 1), got {threshold}")
        with self._lock:
            self.threshold = threshold
            self.metrics = RunningMetrics(self.bend, threshold=threshold)
            for key in ("volumetric_iou", "contact_iou"):
                self._history[key].clear()
            if self._prediction is not None:
                prediction, truth, _ = self._prediction
                self._prediction = (prediction, truth, self._facts(prediction, truth))
            self._publish()

    def models(self) -> tuple[str, ...]:
        names = tuple(bundled_models())
        return names if self._bundled_name() else names + (str(self.choice.checkpoint),)

    def tiers(self) -> tuple[str, ...]:
        return tiers_for(self.live.engine.runtime.device) if self.live is not None else CPU_TIERS

    def current_model(self) -> tuple[str, str]:
        return self._bundled_name() or str(self.choice.checkpoint), self.choice.setting.tier

    def _bundled_name(self) -> str | None:
        for name, path in bundled_models().items():
            if path.resolve() == self.choice.checkpoint.resolve():
                return name
        return None

    def set_model(self, model: str, tier: str) -> None:
        """Load `model` (a bundled name or the session's checkpoint) at `tier` on a background thread; the
        old engine keeps running until the new one is ready, and keeps running if it fails."""
        path = bundled_models().get(model)
        self._switch((self.choice.with_checkpoint(path) if path is not None else self.choice).with_tier(tier))

    def current_rate(self) -> int:
        return self.choice.setting.every

    def set_rate(self, every: int) -> None:
        """Predict every `every`-th frame from now on (the engine is rebuilt on a background thread)."""
        self._switch(self.choice.with_setting(every=every))

    def _switch(self, choice: ModelChoice) -> None:
        if self._loading:
            self.message = "still loading the previous choice"
            return
        self._loading = True
        first_use = " (an ONNX tier's first use exports its graphs in the background: about 15 s)" \
            if choice.setting.runtime == "onnx" and choice.onnx_dir is None else ""
        self.message = f"loading {model_label(choice)}…{first_use}"
        threading.Thread(target=self._load, args=(choice,), name="touchanything-load", daemon=True).start()

    def _load(self, choice: ModelChoice) -> None:
        try:
            engine = build_engine(choice.with_setting(views=VIEW_NAMES))
        except (UserError, OSError, RuntimeError) as exc:
            self.message = f"kept {self._model}: {exc}"
            return
        finally:
            self._loading = False
        label, note = model_label(choice, engine), illustrative_note(choice, camera_pose=True)

        def use() -> None:
            self._engine, self._pose_only, self.choice, self._model, self._camera_note = engine, engine.blank, choice, label, note

        self._restart(setting=True, change=use)  # before the engine runs: its predictions then count
        if self.live is None:
            self.live = LiveEngine(engine, on_prediction=self._on_prediction).start()
        else:
            self.live.replace_engine(engine)
        self.message = f"running {self._model}"
