"""A replay session for the dashboard: the episode played in real time (pause, step, seek, speed) into the
live engine (latest wins, so a slow model drops frames instead of lagging), compared with the episode's
ground truth."""
from __future__ import annotations

import threading

import numpy as np

from touchanything.app.sessions.engine_choice import ModelChoice
from touchanything.app.sessions.engine_session import EngineSession
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.devices.snapshot import Snapshot
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.viz.dashboard.dashboard_state import Playback, SourceStatus


class ReplaySession(EngineSession):
    """Start with `start()`, end with `close()`. `pose_source`: "wilor" (the episode's file), "rokoko" or
    "camera" (estimated from the ego view in the player thread, every frame in order)."""

    def __init__(self, episode: Episode, engine: StreamingEngine | None, choice: ModelChoice,
                 message: str = "", pose_source: str = "wilor") -> None:
        super().__init__(engine, choice, message)
        self.episode = episode
        self.source = ReplaySource(episode, ReplayConfig(speed=1.0, hold_at_end=True, pose_source=pose_source))
        self._speed = 1.0
        self.truth = None
        if episode.pressure is not None:
            self.truth = ground_truth_for_metrics(episode.pressure.grids,
                                                  bool(episode.pressure.attrs.get("normalized", False)))
        self._player = threading.Thread(target=self._play, name="touchanything-replay", daemon=True)

    def start(self) -> ReplaySession:
        self.start_engine()
        self._player.start()
        return self

    def close(self) -> None:
        """Stop playing, then the engine."""
        self.source.close()
        self._player.join(5)
        self.stop_engine()

    def _play(self) -> None:
        for snapshot in self.source:
            self.submit(snapshot)

    def truth_of(self, snapshot: Snapshot) -> np.ndarray | None:
        return None if self.truth is None else self.truth[snapshot.frame_index]

    def playback(self) -> Playback:
        return Playback(self.source.position, self.episode.num_frames, self.source.paused, self._speed)

    def source_rows(self, snapshot: Snapshot | None) -> list[SourceStatus]:
        rows = [SourceStatus("replay", True, self.frames.rate(), self.age_ms(snapshot and snapshot.t_us), 0,
                             f"frame {snapshot.frame_index if snapshot else '-'} of {self.episode.num_frames}")]
        for name, status in (snapshot.source_status.items() if snapshot is not None else ()):
            rows.append(SourceStatus(name, status not in ("absent", "no frame"), detail=status))
        return rows

    def play(self) -> None:
        self.source.resume()

    def pause(self) -> None:
        self.source.pause()

    def step(self) -> None:
        self.source.step()

    def seek(self, frame: int) -> None:
        """Jump to `frame`; the engine's window and the metrics start afresh there."""
        self.restart()
        self.source.seek(frame)

    def set_speed(self, speed: float) -> None:
        self.source.set_speed(speed)
        self._speed = speed

    @property
    def can_record(self) -> bool:
        return False

    def toggle_recording(self) -> None:
        self.message = "recording is for the live rig; a replay is already recorded"
