"""Live sources read by one thread each: the connect/disconnect lifecycle, the latest-value slot, counters.

A source opens its device in `connect()` (a UserError, with everything opened so far closed again, when
that fails), then one reader thread calls `_step()` until `disconnect()`. Each step publishes at most one
sample to a lock-protected latest-value slot: a slow consumer sees the newest sample, never a backlog.
Memory is constant however long it runs (Python integers do not overflow).
"""
from __future__ import annotations

import dataclasses
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Generic, TypeVar

from touchanything.devices.errors import UserError
from touchanything.devices.worker_thread import start_worker, stop_worker

T = TypeVar("T")

RATE_SMOOTHING = 0.1
"""Weight of the newest interval in the exponential average behind the measured rate."""
ERROR_PAUSE_S = 0.01
"""The reader waits this long after a failed step, so a persistent failure cannot spin a core."""


def now_us() -> int:
    """Host monotonic clock in µs: the `t_us` of every sample."""
    return time.monotonic_ns() // 1000


class SourceEnded(Exception):
    """Raised by `_step()` when no more samples will come (end of a file, device gone); the message says why."""


@dataclass
class SourceCounters:
    """samples: published to the slot; unread: replaced in the slot before anyone read them;
    errors: failed reader steps (the reader goes on)."""

    samples: int = 0
    unread: int = 0
    errors: int = 0


class LatestSlot(Generic[T]):
    """The newest sample and its capture time, with the measured arrival rate; thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._value: T | None = None
        self._t_us: int | None = None
        self._unread = False
        self._interval_us: float | None = None

    def put(self, value: T, t_us: int) -> bool:
        """Store `value` captured at `t_us`; True when it replaces a value nobody read."""
        with self._lock:
            if self._t_us is not None and t_us > self._t_us:
                interval = t_us - self._t_us
                self._interval_us = interval if self._interval_us is None else (
                    self._interval_us + RATE_SMOOTHING * (interval - self._interval_us))
            replaced_unread = self._unread
            self._value, self._t_us, self._unread = value, t_us, True
            return replaced_unread

    def get(self) -> T | None:
        """The newest value (None before the first); marks it read."""
        with self._lock:
            self._unread = False
            return self._value

    def summary(self) -> str:
        """"30.0 Hz, age 12 ms", or "no sample yet"."""
        with self._lock:
            t_us, interval = self._t_us, self._interval_us
        if t_us is None:
            return "no sample yet"
        rate = f"{1e6 / interval:.1f} Hz" if interval else "rate unknown"
        return f"{rate}, age {(now_us() - t_us) / 1000:.0f} ms"


class ThreadedSource(ABC, Generic[T]):
    """Base of the live adapters: subclasses implement `_open`, `_step` and `_close` and publish samples
    with `_publish`; they may extend the counters by overriding `_new_counters`."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._slot: LatestSlot[T] = LatestSlot()
        self._lock = threading.Lock()
        self._counters = self._new_counters()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ended: str | None = None
        self._last_error: str | None = None

    def _new_counters(self) -> SourceCounters:
        return SourceCounters()

    @abstractmethod
    def _open(self) -> None:
        """Open the device; raise UserError naming what is wrong. `_close` runs after a failure too."""

    @abstractmethod
    def _step(self) -> None:
        """Read (waiting at most ~0.1 s) and publish at most one sample; raise SourceEnded when done."""

    @abstractmethod
    def _close(self) -> None:
        """Release whatever `_open` got, also when it got only part of it; safe to call twice."""

    @property
    def is_connected(self) -> bool:
        return self._thread is not None

    def connect(self) -> None:
        """Open the device and start the reader thread."""
        if self.is_connected:
            raise UserError(f"{self.name} is already connected; disconnect it first")
        self._slot, self._counters = LatestSlot(), self._new_counters()
        self._ended = self._last_error = None
        self._stop.clear()
        try:
            self._open()
        except BaseException:
            self._close()
            raise
        self._thread = start_worker(self._run, f"{self.name} reader", self._close)

    def disconnect(self) -> None:
        """Stop and join the reader thread, then close the device; does nothing when not connected."""
        if self._thread is None:
            return
        stop_worker(self._thread, self._stop)
        self._thread = None
        self._close()

    def __enter__(self) -> ThreadedSource[T]:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.disconnect()

    def latest(self) -> T | None:
        """The newest sample, or None before the first."""
        return self._slot.get()

    @property
    def counters(self) -> SourceCounters:
        """A consistent copy of the counters."""
        with self._lock:
            return dataclasses.replace(self._counters)

    @property
    def ended(self) -> str | None:
        """Why the reader stopped on its own (end of file, device gone), or None while it runs."""
        return self._ended

    def status(self) -> str:
        """One line for a dashboard, e.g. "connected, 30.0 Hz, age 12 ms, 300 samples, 0 unread, 0 errors"."""
        if not self.is_connected:
            return "disconnected"
        counts = self.counters
        counters = ", ".join(f"{getattr(counts, field.name)} {field.name}" for field in dataclasses.fields(counts))
        state = f"stopped ({self._ended})" if self._ended else "connected"
        error = f", last error: {self._last_error}" if self._last_error else ""
        return f"{state}, {self._slot.summary()}, {counters}{error}"

    def _publish(self, sample: T, t_us: int) -> None:
        replaced_unread = self._slot.put(sample, t_us)
        with self._lock:
            self._counters.samples += 1
            self._counters.unread += replaced_unread

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._step()
            except SourceEnded as end:
                self._ended = str(end)
                return
            except Exception as exc:  # noqa: BLE001 - the reader must outlive a bad sample; counted and shown
                with self._lock:
                    self._counters.errors += 1
                self._last_error = f"{type(exc).__name__}: {exc}"
                self._stop.wait(ERROR_PAUSE_S)
