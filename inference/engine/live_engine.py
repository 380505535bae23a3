"""Live mode: the streaming engine on its own thread, latest-wins.

`submit` never blocks: it puts the snapshot into a one-slot mailbox, replacing (and counting as dropped)
one the engine has not taken yet. So the engine always works on the newest frame and never builds a
backlog; the latency of each prediction (capture → prediction) stays bounded by about two engine steps.

The engine thread runs at a lower scheduling priority (nice +8, where the OS allows it): capture, the rig
clock and the display go first, and the engine takes the CPU they leave, dropping frames to stay current
(on the 2-core CPU the dashboard rendered 28.9–30.2 fps instead of 27.6–28.6 with the nano model).
"""
from __future__ import annotations

import os
import threading
from collections.abc import Callable
from dataclasses import dataclass

from touchanything.core.snapshot import Snapshot
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine

ENGINE_NICENESS = 8


@dataclass
class LiveStats:
    """submitted: snapshots offered; processed: engine steps; dropped: snapshots never processed (replaced in
    the mailbox, or skipped); skipped: of those, the ones the owner did not submit (see `LiveEngine.skip`)."""

    submitted: int = 0
    processed: int = 0
    dropped: int = 0
    skipped: int = 0


class LiveEngine:
    """Use as a context manager (or start/stop). `latest()` is the newest Prediction; `on_prediction` is
    called on the engine thread for each one. An exception in the engine stops the thread and is kept in
    `error` (re-raised by `stop`)."""

    def __init__(self, engine: StreamingEngine, on_prediction: Callable[[Prediction], None] | None = None) -> None:
        self.engine = engine
        self.on_prediction = on_prediction
        self.stats = LiveStats()
        self.error: BaseException | None = None
        self._pending: Snapshot | None = None
        self._calls: list[Callable[[], None]] = []
        self._latest: Prediction | None = None
        self._running = False
        self._wake = threading.Condition()
        self._thread: threading.Thread | None = None

    def start(self) -> LiveEngine:
        self._running = True
        self._thread = threading.Thread(target=self._run, name="touchanything-engine", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 10.0) -> None:
        with self._wake:
            self._running = False
            self._wake.notify()
        if self._thread is not None:
            self._thread.join(timeout)
        if self.error is not None:
            raise self.error

    def __enter__(self) -> LiveEngine:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def submit(self, snapshot: Snapshot) -> None:
        with self._wake:
            self.stats.submitted += 1
            if self._pending is not None:
                self.stats.dropped += 1
            self._pending = snapshot
            self._wake.notify()

    def skip(self) -> None:
        """Count a snapshot the owner did not submit (it gave the CPU to work that cannot drop frames) as
        dropped."""
        with self._wake:
            self.stats.submitted += 1
            self.stats.dropped += 1
            self.stats.skipped += 1

    def call(self, action: Callable[[], None]) -> None:
        """Run `action` on the engine thread before its next step (e.g. reset after a seek, or swap in
        another engine): never while a step is in progress."""
        with self._wake:
            self._calls.append(action)
            self._wake.notify()

    def replace_engine(self, engine: StreamingEngine) -> None:
        """Continue with `engine` from the next snapshot on."""
        self.call(lambda: setattr(self, "engine", engine))

    def latest(self) -> Prediction | None:
        return self._latest

    def idle(self) -> bool:
        """Nothing waiting in the mailbox (the engine may still be working on the last snapshot)."""
        return self._pending is None

    def _take(self) -> tuple[list[Callable[[], None]], Snapshot | None] | None:
        with self._wake:
            while self._running and self._pending is None and not self._calls:
                self._wake.wait()
            if not self._running:
                return None
            calls, self._calls = self._calls, []
            snapshot, self._pending = self._pending, None
            return calls, snapshot

    def _run(self) -> None:
        lower_priority(ENGINE_NICENESS)
        try:
            while (taken := self._take()) is not None:
                calls, snapshot = taken
                for action in calls:
                    action()
                if snapshot is None:
                    continue
                for prediction in self.engine.step(snapshot):
                    self._latest = prediction
                    if self.on_prediction is not None:
                        self.on_prediction(prediction)
                self.stats.processed += 1
        except BaseException as exc:  # kept for the owner thread; the live loop must not die silently
            self.error = exc


def lower_priority(niceness: int) -> None:
    """Raise the calling thread's nice value (Linux: per thread); silently kept where not permitted."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), niceness)
    except (OSError, AttributeError):
        pass
