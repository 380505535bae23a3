"""The rig clock: a thread that takes a Snapshot of every live source's latest valid sample at 30 Hz.

Ticks follow an absolute monotonic schedule (tick k is due at start + k / rate), so no drift builds up.
A late tick is taken at once; ticks whose whole period went by (a stall of the machine or of a
subscriber) are skipped and counted, never delivered in a burst. Each Snapshot is built by
`touchanything.devices.rig.rig_inputs.build_snapshot` (which sample of which source goes where, staleness), handed to every
subscriber on the clock thread, and kept as `latest()`.

The clock follows the one device contract (`ThreadedSource`): `start()` / `stop()` are its `connect()` /
`disconnect()`, `latest()` the newest Snapshot, `rate_hz()` the measured tick rate. It only reads the
sources: connect them before `start()` and disconnect them after `stop()`.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from touchanything.core.errors import UserError
from touchanything.core.snapshot import Snapshot
from touchanything.devices.hardware.threaded_source import SourceCounters, ThreadedSource, now_us
from touchanything.devices.rig.rig_inputs import RigInput, build_snapshot, fill_order

Subscriber = Callable[[Snapshot], None]


@dataclass(frozen=True)
class RigClockConfig:
    """rate_hz: ticks per second. stale_after_ms: a sample older than this at a tick is not used (nor any
    sample of a source that is retrying a lost device: see `rig_inputs.build_snapshot`)."""

    rate_hz: float = 30.0
    stale_after_ms: float = 200.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rate_hz) and 0 < self.rate_hz <= 1000):
            raise UserError(f"rig clock rate must be a number of ticks per second in (0, 1000], got {self.rate_hz}")
        if not (math.isfinite(self.stale_after_ms) and self.stale_after_ms > 0):
            raise UserError(f"rig clock staleness limit must be a positive number of ms, got {self.stale_after_ms}")


@dataclass
class RigClockCounters(SourceCounters):
    """samples (also `ticks`): Snapshots built; skipped: ticks whose period went by entirely; errors: failed
    Snapshot builds and subscriber calls (the clock goes on); unread: Snapshots nobody took with `latest()`."""

    skipped: int = 0

    @property
    def ticks(self) -> int:
        """Snapshots built."""
        return self.samples


class RigClock(ThreadedSource[Snapshot]):
    """`start()` / `stop()` (or `with clock:`); `subscribe(callback)` and `latest()` give the Snapshots."""

    def __init__(self, inputs: Sequence[RigInput], config: RigClockConfig = RigClockConfig()) -> None:
        names = [rig_input.name for rig_input in inputs]
        if len(set(names)) != len(names):
            raise UserError(f"rig source names must be unique, got {', '.join(names)}")
        super().__init__("rig clock")
        self.config = config
        self._inputs = fill_order(inputs)
        self._period_ns = round(1e9 / config.rate_hz)
        self._subscribers: tuple[Subscriber, ...] = ()
        self._started_ns = 0
        self._index = 0

    def _new_counters(self) -> RigClockCounters:
        return RigClockCounters()

    @property
    def counters(self) -> RigClockCounters:
        return super().counters  # type: ignore[return-value]

    def subscribe(self, callback: Subscriber) -> None:
        """Call `callback(snapshot)` on the clock thread at every tick; it should return quickly (a slow
        one makes ticks skip), and what it raises is counted, not propagated."""
        with self._lock:
            self._subscribers += (callback,)

    def unsubscribe(self, callback: Subscriber) -> None:
        """Stop calling `callback` (from the next tick on)."""
        with self._lock:
            self._subscribers = tuple(s for s in self._subscribers if s != callback)

    def status(self) -> str:
        """One line, e.g. "running, 30.0 Hz, 600 ticks, 0 skipped, 0 errors"."""
        counters = self.counters
        tail = f"{counters.ticks} ticks, {counters.skipped} skipped, {counters.errors} errors{self._error_suffix()}"
        return f"running, {self.rate_hz():.1f} Hz, {tail}" if self.is_connected else f"stopped, {tail}"

    def _open(self) -> None:
        self._started_ns, self._index = time.monotonic_ns(), 0

    def _close(self) -> None:
        """The clock holds no device."""

    def _step(self) -> None:
        """Wait for the next due tick (absolute schedule), take it, and skip the ticks that went by."""
        due_ns = self._started_ns + self._index * self._period_ns
        if self._stop.wait(max(due_ns - time.monotonic_ns(), 0) / 1e9):
            return
        self._tick()
        newest_due = (time.monotonic_ns() - self._started_ns) // self._period_ns
        skipped = max(newest_due - self._index - 1, 0)
        self._count(skipped=skipped)
        self._index += 1 + skipped

    def _tick(self) -> None:
        """Build one Snapshot and hand it to the subscribers; failures are counted."""
        try:
            snapshot = build_snapshot(self._inputs, self.counters.ticks, now_us(),
                                      round(self.config.stale_after_ms * 1000))
        except Exception as exc:  # noqa: BLE001 - a bad reading or pose hook must not stop the clock
            self._note_error(exc)
            return
        self._publish(snapshot, snapshot.t_us)
        with self._lock:
            subscribers = self._subscribers
        for callback in subscribers:
            try:
                callback(snapshot)
            except Exception as exc:  # noqa: BLE001 - one failing subscriber must not stop the others
                self._note_error(exc)
