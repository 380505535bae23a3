"""A replay session for the dashboard: the episode played in real time (pause, step, seek, speed) into the
live engine (latest wins, so a slow model drops frames instead of lagging), with the running official
metrics of the frames it predicted, per-stage timings, source status, and model / view / threshold
switches that never block the caller."""
from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque

import numpy as np

from app.engine_choice import CPU_TIERS, ModelChoice, build_engine, bundled_models, model_label
from app.rate_meter import RateMeter, StageMeans
from devices.episode import Episode
from devices.errors import UserError
from devices.replay import ReplayConfig, ReplaySource
from devices.snapshot import VIEW_NAMES, Snapshot
from devices.tactile_layout import TactileLayout
from inference.live_engine import LiveEngine
from inference.metrics import CONTACT_THRESHOLD, ground_truth_for_metrics
from inference.prediction import Prediction
from inference.running_metrics import RunningMetrics
from inference.streaming_engine import StreamingEngine
from viz.dashboard_state import Playback, SessionState, SourceStatus

HISTORY = 300
"""Samples kept for the plots (10 s at 30 fps)."""


class ReplaySession:
    """Start with `start()`, end with `close()`. `engine` None (its model failed to load) still plays the
    cameras and ground truth; `set_model` may bring a model in later."""

    def __init__(self, episode: Episode, engine: StreamingEngine | None, choice: ModelChoice,
                 message: str = "") -> None:
        self.episode = episode
        self.views = tuple(VIEW_NAMES)
        self.threshold = CONTACT_THRESHOLD
        self.choice = choice
        self.source = ReplaySource(episode, ReplayConfig(speed=1.0, hold_at_end=True))
        self._speed = 1.0
        self.truth = None
        if episode.pressure is not None:
            self.truth = ground_truth_for_metrics(episode.pressure.grids,
                                                  bool(episode.pressure.attrs.get("normalized", False)))
        self._bend = TactileLayout.default().bend
        self.metrics = RunningMetrics(self._bend) if self.truth is not None else None
        self._lock = threading.Lock()
        self._recent: dict[int, Snapshot] = {}
        self._snapshot: Snapshot | None = None
        self._prediction: Prediction | None = None
        self._history = {name: deque(maxlen=HISTORY) for name in ("volumetric_iou", "contact_iou", "latency_ms")}
        self._stages = StageMeans()
        self._frames, self._predictions = RateMeter(), RateMeter()
        self._message = message
        self._loading = False
        self._model = model_label(choice) if engine is not None else "no model"
        self.live = LiveEngine(engine, on_prediction=self._on_prediction) if engine is not None else None
        self._player = threading.Thread(target=self._play, name="touchanything-replay", daemon=True)

    def start(self) -> "ReplaySession":
        if self.live is not None:
            self.live.start()
        self._player.start()
        return self

    def close(self) -> None:
        """Stop playing and the engine; an engine error is reported in the message, not raised."""
        self.source.close()
        self._player.join(5)
        if self.live is not None:
            try:
                self.live.stop()
            except Exception as exc:  # the session is ending; the error was already shown
                self._message = f"engine stopped with an error: {exc}"

    def _play(self) -> None:
        for snapshot in self.source:
            with self._lock:
                self._snapshot = snapshot
                self._recent[snapshot.frame_index] = snapshot
                while len(self._recent) > 64:
                    self._recent.pop(next(iter(self._recent)))
            self._frames.tick()
            if self.live is not None:
                self.live.submit(self._for_engine(snapshot))

    def _for_engine(self, snapshot: Snapshot) -> Snapshot:
        """The snapshot with only the views switched on."""
        return dataclasses.replace(snapshot, images={v: im for v, im in snapshot.images.items() if v in self.views})

    def _on_prediction(self, prediction: Prediction) -> None:
        """Engine thread: keep the prediction, feed the metrics (frames before a seek are ignored)."""
        with self._lock:
            if prediction.frame_index not in self._recent:
                return
            self._prediction = prediction
            self._predictions.tick()
            self._stages.add(prediction.timings_ms)
            self._history["latency_ms"].append(prediction.latency_ms)
            if self.metrics is not None and prediction.pressure is not None:
                self.metrics.add(prediction.pressure, self.truth[prediction.frame_index])
                rolling = self.metrics.rolling()
                self._history["volumetric_iou"].append(rolling["volumetric_iou"])
                self._history["contact_iou"].append(rolling["contact_iou"])

    def state(self) -> SessionState:
        with self._lock:
            prediction, snapshot = self._prediction, self._snapshot
            truth = None
            if prediction is not None and self.truth is not None:
                truth = self.truth[prediction.frame_index]
            metrics = self.metrics
            return SessionState(
                snapshot=snapshot, prediction=prediction, truth=truth,
                rolling=metrics.rolling() if metrics is not None else None,
                cumulative=metrics.cumulative() if metrics is not None else None,
                metric_frames=metrics.frames if metrics is not None else 0,
                history={name: np.array(values, np.float64) for name, values in self._history.items()},
                stage_ms=self._stages.means(), engine_fps=self._predictions.rate(),
                sources=self._sources(snapshot),
                playback=Playback(self.source.position, self.episode.num_frames, self.source.paused, self._speed),
                model=self._model, message=self._message)

    def _sources(self, snapshot: Snapshot | None) -> tuple[SourceStatus, ...]:
        age = None if snapshot is None else time.monotonic() * 1e3 - snapshot.t_us / 1e3
        rows = [SourceStatus("replay", True, self._frames.rate(), age, 0,
                             f"frame {snapshot.frame_index if snapshot else '-'} of {self.episode.num_frames}")]
        for name, status in (snapshot.source_status.items() if snapshot is not None else ()):
            rows.append(SourceStatus(name, status not in ("absent", "no frame"), None, None, 0, status))
        if self.live is not None:
            stats = self.live.stats
            detail = "loading a model…" if self._loading else f"{stats.processed} processed"
            rows.append(SourceStatus("engine", self.live.error is None, self._predictions.rate(), None,
                                     stats.dropped, detail if self.live.error is None else f"error: {self.live.error}"))
        return tuple(rows)

    def play(self) -> None:
        self.source.resume()

    def pause(self) -> None:
        self.source.pause()

    def step(self) -> None:
        self.source.step()

    def seek(self, frame: int) -> None:
        """Jump to `frame`; the engine's window and the metrics start afresh there."""
        with self._lock:
            self._recent.clear()
            if self.metrics is not None:
                self.metrics.reset()
            for values in self._history.values():
                values.clear()
        self.source.seek(frame)
        if self.live is not None:
            self.live.call(lambda: self.live.engine.reset())

    def set_speed(self, speed: float) -> None:
        self.source.set_speed(speed)
        self._speed = speed

    def set_views(self, views: tuple[str, ...]) -> None:
        """Views the model may use from the next frame on ("ego" off: no prediction, with the reason)."""
        self.views = tuple(v for v in VIEW_NAMES if v in views)

    def set_threshold(self, threshold: float) -> None:
        """Contact threshold for the metrics and indicators (official 0.1); the metrics restart."""
        if not 0.0 < threshold < 1.0:
            raise UserError(f"contact threshold must lie in (0, 1), got {threshold}")
        with self._lock:
            self.threshold = threshold
            if self.metrics is not None:
                self.metrics = RunningMetrics(self._bend, threshold=threshold)

    def models(self) -> tuple[str, ...]:
        names = tuple(bundled_models())
        label = str(self.choice.checkpoint)
        return names if self._bundled_name() else names + (label,)

    def tiers(self) -> tuple[str, ...]:
        return CPU_TIERS

    def current_model(self) -> tuple[str, str]:
        return self._bundled_name() or str(self.choice.checkpoint), self.choice.tier

    def _bundled_name(self) -> str | None:
        for name, path in bundled_models().items():
            if path.resolve() == self.choice.checkpoint.resolve():
                return name
        return None

    def set_model(self, model: str, tier: str) -> None:
        """Load `model` (a bundled name or a checkpoint path) at `tier` on a background thread; the old
        engine keeps running until the new one is ready, and keeps running if it fails."""
        if self._loading:
            self._message = "still loading the previous choice"
            return
        path = bundled_models().get(model)
        choice = ModelChoice(path, None) if path is not None else dataclasses.replace(self.choice)
        choice = choice.with_tier(tier)
        self._loading = True
        self._message = f"loading {model_label(choice)}…"
        threading.Thread(target=self._load, args=(choice,), name="touchanything-load", daemon=True).start()

    def _load(self, choice: ModelChoice) -> None:
        try:
            engine = build_engine(choice, VIEW_NAMES)
        except (UserError, OSError, RuntimeError) as exc:
            self._message = f"kept {self._model}: {exc}"
            return
        finally:
            self._loading = False
        if self.live is None:
            self.live = LiveEngine(engine, on_prediction=self._on_prediction).start()
        else:
            self.live.replace_engine(engine)
        self.choice, self._model = choice, model_label(choice)
        self._message = f"running {self._model}"

    @property
    def can_record(self) -> bool:
        return False

    def toggle_recording(self) -> None:
        self._message = "recording is for the live rig; a replay is already recorded"
