"""The rig clock: a thread that takes a Snapshot of every live source's latest valid sample at 30 Hz.

Ticks follow an absolute monotonic schedule (tick k is due at start + k / rate), so no drift builds up.
A late tick is taken at once; ticks whose whole period went by (a stall of the machine or of a
subscriber) are skipped and counted, never delivered in a burst. Each Snapshot is built by
`touchanything.devices.rig.rig_inputs.build_snapshot` (which sample of which source goes where, staleness), handed to every
subscriber on the clock thread, and kept as `latest()`.

The clock only reads the sources: connect them before `start()` and disconnect them after `stop()`.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from touchanything.devices.errors import UserError
from touchanything.devices.hardware.threaded_source import now_us
from touchanything.devices.rig.rig_inputs import RigInput, build_snapshot, fill_order
from touchanything.devices.snapshot import Snapshot
from touchanything.devices.worker_thread import start_worker, stop_worker

Subscriber = Callable[[Snapshot], None]


@dataclass(frozen=True)
class RigClockConfig:
    """rate_hz: ticks per second. stale_after_ms: a sample older than this at a tick is not used."""

    rate_hz: float = 30.0
    stale_after_ms: float = 200.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 0 < self.rate_hz <= 1000):
            raise UserError(f"rig clock rate must be a number of ticks per second in (0, 1000], got {self.rate_hz}")
        if not (math.isfinite(self.stale_after_ms) and self.stale_after_ms > 0):
            raise UserError(f"rig clock staleness limit must be a positive number of ms, got {self.stale_after_ms}")


@dataclass(frozen=True)
class RigClockCounters:
    """ticks: Snapshots built; skipped: ticks whose period went by entirely; errors: failed Snapshot
    builds and subscriber calls (the clock goes on)."""

    ticks: int = 0
    skipped: int = 0
    errors: int = 0


class RigClock:
    """`start()` / `stop()` (or `with clock:`); `subscribe(callback)` and `latest()` give the Snapshots."""

    def __init__(self, inputs: Sequence[RigInput], config: RigClockConfig = RigClockConfig()) -> None:
        names = [rig_input.name for rig_input in inputs]
        if len(set(names)) != len(names):
            raise UserError(f"rig source names must be unique, got {', '.join(names)}")
        self.config = config
        self._inputs = fill_order(inputs)
        self._period_ns = round(1e9 / config.rate_hz)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._subscribers: tuple[Subscriber, ...] = ()
        self._latest: Snapshot | None = None
        self._counters = RigClockCounters()
        self._started_ns = 0
        self._last_error = ""

    @property
    def is_running(self) -> bool:
        return self._thread is not None

    def subscribe(self, callback: Subscriber) -> None:
        """Call `callback(snapshot)` on the clock thread at every tick; it should return quickly (a slow
        one makes ticks skip), and what it raises is counted, not propagated."""
        with self._lock:
            self._subscribers += (callback,)

    def unsubscribe(self, callback: Subscriber) -> None:
        """Stop calling `callback` (from the next tick on)."""
        with self._lock:
            self._subscribers = tuple(s for s in self._subscribers if s != callback)

    def latest(self) -> Snapshot | None:
        """The newest Snapshot, or None before the first tick."""
        with self._lock:
            return self._latest

    @property
    def counters(self) -> RigClockCounters:
        with self._lock:
            return replace(self._counters)

    def start(self) -> None:
        """Start ticking (the first tick at once)."""
        if self.is_running:
            raise RuntimeError("the rig clock is already running")
        self._stop.clear()
        with self._lock:
            self._counters, self._latest, self._last_error = RigClockCounters(), None, ""
        self._started_ns = time.monotonic_ns()
        self._thread = start_worker(self._run, "rig-clock")

    def stop(self) -> None:
        """Stop and join the clock thread; does nothing when not running."""
        stop_worker(self._thread, self._stop)
        self._thread = None

    def __enter__(self) -> RigClock:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def status(self) -> str:
        """One line, e.g. "running, 30.0 Hz, 600 ticks, 0 skipped, 0 errors"."""
        counters = self.counters
        tail = f"{counters.ticks} ticks, {counters.skipped} skipped, {counters.errors} errors"
        tail += f", last error: {self._last_error}" if self._last_error else ""
        if not self.is_running:
            return f"stopped, {tail}"
        elapsed_s = (time.monotonic_ns() - self._started_ns) / 1e9
        rate = counters.ticks / elapsed_s if elapsed_s > 0 else 0.0
        return f"running, {rate:.1f} Hz, {tail}"

    def _run(self) -> None:
        index = 0
        while not self._stop.wait(max(self._started_ns + index * self._period_ns - time.monotonic_ns(), 0) / 1e9):
            self._tick()
            newest_due = (time.monotonic_ns() - self._started_ns) // self._period_ns
            skipped = max(newest_due - index - 1, 0)
            with self._lock:
                self._counters = replace(self._counters, skipped=self._counters.skipped + skipped)
            index += 1 + skipped

    def _tick(self) -> None:
        """Build one Snapshot and hand it to the subscribers; failures are counted."""
        try:
            snapshot = build_snapshot(self._inputs, self._counters.ticks, now_us(),
                                      round(self.config.stale_after_ms * 1000))
        except Exception as exc:  # noqa: BLE001 - a bad reading or pose hook must not stop the clock
            self._count_error(exc)
            return
        with self._lock:
            self._latest = snapshot
            self._counters = replace(self._counters, ticks=self._counters.ticks + 1)
            subscribers = self._subscribers
        for callback in subscribers:
            try:
                callback(snapshot)
            except Exception as exc:  # noqa: BLE001 - one failing subscriber must not stop the others
                self._count_error(exc)

    def _count_error(self, exc: Exception) -> None:
        with self._lock:
            self._counters = replace(self._counters, errors=self._counters.errors + 1)
            self._last_error = f"{type(exc).__name__}: {exc}"
