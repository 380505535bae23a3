"""A replay session for the dashboard: the episode played in real time (pause, step, seek, speed) into the
live engine (latest wins, so a slow model drops frames instead of lagging), compared with the episode's
ground truth."""
from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from touchanything.app.sessions.engine_choice import ModelChoice
from touchanything.app.sessions.engine_session import EngineSession
from touchanything.core.snapshot import Snapshot
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.rig.replay import ReplayConfig, ReplaySource
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.metrics import ground_truth_for_metrics
from touchanything.viz.dashboard.dashboard_state import Playback, SourceStatus


class ReplaySession(EngineSession):
    """Start with `start()`, end with `close()`. `pose_source`: "wilor" (the episode's file), "rokoko" or
    "camera" (estimated from the ego view in the player thread, every frame in order). `loop`: play the
    episode again from its start, engine and metrics afresh, until closed (else hold at its end). `tour`: more
    episodes, played after `episode` in turn (each from its start, engine and metrics afresh), then `episode`
    again, until closed."""

    def __init__(self, episode: Episode, engine: StreamingEngine | None, choice: ModelChoice,
                 message: str = "", pose_source: str = "wilor", loop: bool = False, tour: Sequence[Episode] = ()) -> None:
        super().__init__(engine, choice, message)
        self.episodes = [episode, *tour]
        self.loop, self.pose_source = loop, pose_source
        self.passes = 1
        """How many times playing reached the first frame from the last (loop), or the next episode (tour)."""
        self._speed = 1.0
        self._closed = False
        self._show(0)
        self._player = threading.Thread(target=self._play, name="touchanything-replay", daemon=True)

    def _show(self, index: int) -> None:
        """Make episode `index` of the tour the one played (from its start) and compared."""
        episode = self.episodes[index]
        touring = len(self.episodes) > 1
        config = ReplayConfig(speed=self._speed, loop=self.loop and not touring, hold_at_end=not self.loop and not touring,
                              pose_source=self.pose_source)
        self.index, self.episode, self.source = index, episode, ReplaySource(episode, config)
        self.truth = None
        if episode.pressure is not None:
            self.truth = ground_truth_for_metrics(episode.pressure.grids,
                                                  bool(episode.pressure.attrs.get("normalized", False)))

    def start(self) -> ReplaySession:
        self.start_engine()
        self._player.start()
        return self

    def close(self) -> None:
        """Stop playing, then the engine."""
        self._closed = True
        self.source.close()
        self._player.join(5)
        self.stop_engine()

    def _play(self) -> None:
        while True:
            last, previous = self.episode.num_frames - 1, None
            for snapshot in self.source:
                if previous == last and snapshot.frame_index == 0:
                    self.passes += 1
                    self.restart()
                previous = snapshot.frame_index
                self.submit(snapshot)
            if self._closed or len(self.episodes) == 1:
                return
            paused = self.source.paused
            self._show((self.index + 1) % len(self.episodes))
            if paused:
                self.source.pause()
            self.passes += 1
            self.restart()

    def truth_of(self, snapshot: Snapshot) -> np.ndarray | None:
        return None if self.truth is None else self.truth[snapshot.frame_index]

    def playback(self) -> Playback:
        return Playback(self.source.position, self.episode.num_frames, self.source.paused, self._speed)

    def source_rows(self, snapshot: Snapshot | None) -> list[SourceStatus]:
        paused = self.source.paused  # no new samples: no age, no rate (not the last ones as if running)
        age = None if paused else self.age_ms(snapshot and snapshot.t_us)
        tour = f"episode {self.index + 1} of {len(self.episodes)}, " if len(self.episodes) > 1 else ""
        rows = [SourceStatus("replay", True, None if paused else self.frames.rate(), age, 0,
                             f"{tour}frame {snapshot.frame_index if snapshot else '-'} of {self.episode.num_frames}")]
        for name, status in (snapshot.source_status.items() if snapshot is not None else ()):
            absent = status == "absent"  # the episode has no such stream
            rows.append(SourceStatus(name, not absent and status != "no frame", detail="" if absent or status == "ok" else status,
                                     in_scene=not absent))
        return rows

    def play(self) -> None:
        self.source.resume()

    def pause(self) -> None:
        self.source.pause()

    def step(self) -> None:
        self.source.step()

    def seek(self, frame: int) -> None:
        """Jump to `frame`; the engine's window and the metrics start afresh there (a frame the source took
        before the seek is not counted)."""
        target = self.source.seek_target(frame)
        self.restart(sought=target)
        self.source.seek(target)

    def set_speed(self, speed: float) -> None:
        self.source.set_speed(speed)
        self._speed = speed

    def toggle_recording(self) -> None:
        """A replay records nothing (it is a recording already): says so, and how to export it."""
        self.message = ("Record is for the live rig: this replay is a recording already. To keep what you see, "
                        "export it: touchanything replay EPISODE --headless (a comparison video).")
