"""A session's Rerun recording fed off the live path: the rig (or replay) thread and the engine thread only
append to a bounded queue (constant time, never blocking) and one logging thread of its own, at a low
priority, encodes and logs. When logging falls behind, the oldest items are dropped and counted, so memory
stays bounded however long the session runs."""
from __future__ import annotations

import os
import threading
import time
from collections import Counter, deque
from collections.abc import Callable

import numpy as np

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.live_engine import ENGINE_NICENESS, lower_priority
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.evaluation.metrics import CONTACT_THRESHOLD
from touchanything.viz.frame_facts import FrameFacts, frame_facts
from touchanything.viz.rerun_recording import RerunRecording

MAX_PENDING = 16
"""Items waiting for the logging thread at most (about half a second of the rig's snapshots)."""
LOGGER_NICENESS_ABOVE = 2
"""The logging thread's nice value is this much above the engine thread's and the process's (whichever is
higher): it yields to the engine, and to capture and display before it, also in a process started with `nice`."""


class RerunSink:
    """`observe` each snapshot and `predicted` each prediction; `close()` logs what is queued, stops the thread
    and closes nothing else (the caller closes the recording). `time_of(snapshot)`: its capture time in seconds
    from the start (a replay: the episode's timestamps; live: from the first snapshot)."""

    def __init__(self, recording: RerunRecording, bend: np.ndarray, time_of: Callable[[Snapshot], float]) -> None:
        self.recording = recording
        self.bend = bend
        self.time_of = time_of
        self.logged = 0
        self.dropped = 0
        self.dropped_kinds: Counter[str] = Counter()
        """{"observation" | "prediction": items dropped}."""
        self.busy_s = 0.0
        self.error: BaseException | None = None
        self._queue: deque[tuple[str, Callable[[], None]]] = deque()
        self._wake = threading.Condition()
        self._running = True
        self._thread = threading.Thread(target=self._run, name="touchanything-rerun", daemon=True)
        self._thread.start()

    @property
    def pending(self) -> int:
        """Items waiting for the logging thread (at most MAX_PENDING)."""
        return len(self._queue)

    def _put(self, kind: str, job: Callable[[], None]) -> None:
        with self._wake:
            if len(self._queue) >= MAX_PENDING:
                self.dropped_kinds[self._queue.popleft()[0]] += 1
                self.dropped += 1
            self._queue.append((kind, job))
            self._wake.notify()

    def observe(self, snapshot: Snapshot, truth: np.ndarray | None, threshold: float = CONTACT_THRESHOLD,
                used: tuple[str, ...] = VIEW_NAMES) -> None:
        """The rig's snapshot and its measured pressure (2, 21, 21) or None, whose facts (contact at `threshold`)
        the logging thread derives; `used`: the views the model takes anything from now."""
        def job() -> None:
            facts = frame_facts(None, None, truth, self.bend, threshold)
            self.recording.log_observation(snapshot.frame_index, self.time_of(snapshot), snapshot.images, snapshot.joints,
                                           snapshot.joints_valid, truth, facts, snapshot.trackers, used)
        self._put("observation", job)

    def predicted(self, prediction: Prediction, snapshot: Snapshot, truth: np.ndarray | None, facts: FrameFacts) -> None:
        """The engine's prediction of `snapshot`'s frame, its measured pressure and the prediction's facts (the
        same record the dashboard shows)."""
        def job() -> None:
            self.recording.log_prediction(prediction.frame_index, self.time_of(snapshot), prediction.pressure, facts,
                                          snapshot.joints, snapshot.joints_valid, truth, prediction.latency_ms,
                                          prediction.timings_ms.get("total"), prediction.spread)
        self._put("prediction", job)

    def _run(self) -> None:
        try:
            current = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
        except (OSError, AttributeError):
            current = 0
        lower_priority(min(19, max(current, ENGINE_NICENESS) + LOGGER_NICENESS_ABOVE))
        while True:
            with self._wake:
                while self._running and not self._queue:
                    self._wake.wait()
                if not self._queue:
                    return
                job = self._queue.popleft()[1]
            start = time.perf_counter()
            try:
                job()
                self.logged += 1
            except Exception as exc:  # kept for the owner: a logging failure must not stop the session
                self.error = exc
            self.busy_s += time.perf_counter() - start

    def close(self) -> None:
        """Log what is queued, then stop the thread."""
        with self._wake:
            self._running = False
            self._wake.notify()
        self._thread.join()

    def line(self) -> str:
        """"rerun     1180 items logged (3.1 ms each), 4 dropped while the logger was behind (3 observations,
        1 predictions)[; error: …]" (no parenthesis when none was dropped)."""
        each = 1e3 * self.busy_s / max(self.logged, 1)
        kinds = ", ".join(f"{n} {kind}s" for kind, n in sorted(self.dropped_kinds.items()))
        error = f"; error: {self.error}" if self.error is not None else ""
        return (f"rerun     {self.logged} items logged ({each:.1f} ms each), {self.dropped} dropped while the logger was behind"
                + (f" ({kinds})" if kinds else "") + error)


def seconds_since_first() -> Callable[[Snapshot], float]:
    """A snapshot's capture time in seconds from the first snapshot asked about (the live rig's clock)."""
    first: list[int] = []

    def time_of(snapshot: Snapshot) -> float:
        if not first:
            first.append(snapshot.t_us)
        return (snapshot.t_us - first[0]) / 1e6

    return time_of
