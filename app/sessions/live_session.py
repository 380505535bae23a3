"""A live session for the dashboard: the rig clock's snapshots into the live engine (latest wins), the
gloves' measured pressure beside the prediction, source status from every adapter, and recording."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from touchanything.app.sessions.bundled import OUTPUT_DIR
from touchanything.app.sessions.engine_choice import ModelChoice
from touchanything.app.sessions.engine_session import EngineSession
from touchanything.app.sessions.scene_rig import LiveRig
from touchanything.core.errors import UserError
from touchanything.core.snapshot import Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.rig.live_tactile import LiveTactile
from touchanything.devices.rig.recorder import Recorder, RecorderConfig
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.viz.dashboard.dashboard_state import SourceStatus

RECORDINGS = OUTPUT_DIR / "live"
"""Where the dashboard's Record button writes a live session (the screenshots go to recordings/screenshots)."""


class LiveSession(EngineSession):
    """`start()` brings the rig up (raising UserError when a device is absent), `close()` takes it down.
    Recordings go to `recordings_dir/Live/session/<start time>/` (a raw EgoTouch episode folder)."""

    def __init__(self, rig: LiveRig, engine: StreamingEngine | None, choice: ModelChoice, message: str = "",
                 recordings_dir: Path = RECORDINGS) -> None:
        super().__init__(engine, choice, message)
        self.rig = rig
        self.recordings_dir = recordings_dir
        self.tactile = LiveTactile(TactileLayout.default())
        self.recorder: Recorder | None = None

    def start(self) -> LiveSession:
        clock = self.rig.start()
        self.start_engine()
        clock.subscribe(self._on_snapshot)
        return self

    def close(self) -> None:
        """Stop recording (keeping what was written), the rig, then the engine."""
        if self.recorder is not None:
            self.toggle_recording()
        self.rig.stop()
        self.stop_engine()

    def _on_snapshot(self, snapshot: Snapshot) -> None:
        """Rig clock thread. A recording comes first: while the recorder is behind, the engine skips frames
        (live mode drops them anyway) so that the CPU goes to writing, which must not drop any."""
        recorder = self.recorder
        if recorder is not None:
            recorder.write(snapshot)
        self.submit(snapshot, predict=recorder is None or not recorder.is_behind)

    def truth_of(self, snapshot: Snapshot) -> np.ndarray | None:
        """The gloves' pressure through the live tactile pipeline; a hand without a glove sample is NaN."""
        if snapshot.pressure_raw is None:
            return None
        grid = self.tactile.grid(snapshot.pressure_raw)
        present = snapshot.glove_present if snapshot.glove_present is not None else np.ones(2, bool)
        grid[~np.asarray(present, bool)] = np.nan
        return grid

    def source_rows(self, snapshot: Snapshot | None) -> list[SourceStatus]:
        rows = []
        status = snapshot.source_status if snapshot is not None else {}
        ages = snapshot.source_age_ms if snapshot is not None else {}
        for name, device in self.rig.sources.items():
            state = status.get(name, "")
            rows.append(SourceStatus(name, state.startswith("ok"), device.rate_hz(), ages.get(name), 0, device.status()))
        clock = self.rig.clock
        if clock is not None:
            counters = clock.counters
            rows.insert(0, SourceStatus("rig clock", True, self.frames.rate(), self.age_ms(snapshot and snapshot.t_us),
                                        counters.skipped, f"{counters.ticks} ticks"))
        return rows

    def recording_status(self) -> str | None:
        return None if self.recorder is None else self.recorder.status()

    def toggle_recording(self) -> None:
        """Start a new recording, or stop the current one (its folder is complete and replayable)."""
        if self.recorder is None:
            folder = self.recordings_dir / "Live" / "session" / time.strftime("%Y%m%d_%H%M%S")
            recorder = Recorder(RecorderConfig(folder, fsync_s=self.rig.scene.recording.fsync_s))
            try:
                recorder.start()
            except UserError as exc:
                self.message = str(exc)
                return
            self.recorder = recorder
            self.message = f"recording to {folder}"
            return
        recorder, self.recorder = self.recorder, None
        try:
            counters = recorder.stop()
            self.message = f"recorded {counters.written} frames ({counters.dropped} dropped) to {recorder.config.folder}"
        except UserError as exc:
            self.message = f"recording stopped: {exc}"

    def play(self) -> None:
        """Live has no transport."""

    pause = step = play

    def seek(self, frame: int) -> None:
        """Live has no transport."""

    def set_speed(self, speed: float) -> None:
        """Live has no transport."""
