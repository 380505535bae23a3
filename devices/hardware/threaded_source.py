"""The one device contract: every live source (cameras, gloves, hand mocap, trackers, the simulated rig's
trackers) and the rig clock is a `ThreadedSource`, after lerobot's camera interface.

Contract (what callers may rely on):
- `connect()` opens the device and starts one reader thread. It raises `DeviceAlreadyConnectedError` when
  already connected, and a `UserError` naming what is wrong when the device cannot be opened; everything
  opened so far is then closed again and no thread is left.
- `disconnect()` stops and joins the reader thread, then closes the device; it does nothing when not
  connected (so it is safe in `finally` blocks). `with source:` is connect ... disconnect.
- `is_connected` is True between a successful connect and disconnect, also while a device that went away
  is being retried (`retrying`) or after the reader stopped on its own (`ended` says why).
- A device that goes away while connected (`_step` raises `DeviceLost`) is closed and reopened by the reader
  with back-off (`reconnect_backoff_s`: first wait, doubling up to the longest) until it returns; meanwhile
  `retrying` is True and `status()` reads "disconnected, retrying (<reason>) every ≤ 2 s, ...". Each
  successful reopen counts one `reconnects`. The end of a finite stream (`SourceEnded`) is not retried.
- `latest()` is the newest sample, or None before the first: a lock-protected latest-value slot, so a slow
  consumer sees the newest sample, never a backlog, and memory stays constant however long it runs.
  Samples carry `t_us`, the host monotonic clock in µs (`now_us()`).
- `rate_hz()` is the measured sample rate (one `RateMeter` over the capture times), `age_ms()` the age of
  the newest sample; `counters` is a consistent copy of the counters (`SourceCounters` or a subclass);
  `status()` is one line for a dashboard.

A subclass implements `_open`, `_step` and `_close`, publishes with `_publish`, and may extend the counters
(`_new_counters`, `_count`) and the status line (`_status_details`, or `status` itself). It raises
`DeviceLost(reason)` from `_step` when its device is gone, and may override `_reopen` (default: `_open`).
"""
from __future__ import annotations

import dataclasses
import math
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Generic, TypeVar

from touchanything.core.errors import DeviceAlreadyConnectedError, UserError
from touchanything.devices.rate_meter import RateMeter
from touchanything.devices.worker_thread import start_worker, stop_worker

T = TypeVar("T")

ERROR_PAUSE_S = 0.01
"""The reader waits this long after a failed step, so a persistent failure cannot spin a core."""
RATE_WINDOW = 30
"""Samples over which a source's rate is measured, unless the source says otherwise."""
DEFAULT_BACKOFF_S = (0.1, 2.0)
"""(first wait, longest wait) in seconds between attempts to reopen a device that went away."""


def now_us() -> int:
    """Host monotonic clock in µs: the `t_us` of every sample."""
    return time.monotonic_ns() // 1000


class SourceEnded(Exception):
    """Raised by `_step()` when no more samples will come (the end of a file or of a finite replay, not a
    device that went away: that is `DeviceLost`); the message says why."""


class DeviceLost(Exception):
    """Raised by `_step()` when the device went away (its open or read fails, a live device sent nothing for
    longer than its timeout, its path vanished); the message says why. The reader closes the device and
    reopens it with back-off until it returns."""


def check_backoff(value: object, what: str) -> tuple[float, float]:
    """A (first, longest) back-off in seconds as a tuple (TOML gives a list); UserError naming `what`
    unless 0 < first <= longest and both finite."""
    backoff = tuple(value) if isinstance(value, (tuple, list)) else ()
    try:
        ok = len(backoff) == 2 and 0 < backoff[0] <= backoff[1] and math.isfinite(backoff[1])
    except TypeError:
        ok = False
    if not ok:
        raise UserError(f"{what} reconnect back-off must be (first, longest) seconds with 0 < first <= longest, "
                        f"got {value}")
    return float(backoff[0]), float(backoff[1])


@dataclass
class SourceCounters:
    """samples: published to the slot; unread: replaced in the slot before anyone read them;
    errors: failed reader steps (the reader goes on); reconnects: reopenings of a device that went away."""

    samples: int = 0
    unread: int = 0
    errors: int = 0
    reconnects: int = 0


class LatestSlot(Generic[T]):
    """The newest sample and its capture time, with the measured rate of the samples; thread-safe."""

    def __init__(self, rate_window: int = RATE_WINDOW) -> None:
        self._lock = threading.Lock()
        self._value: T | None = None
        self._t_us: int | None = None
        self._unread = False
        self._rate = RateMeter(rate_window)

    def put(self, value: T, t_us: int, samples: int = 1) -> bool:
        """Store `value` captured at `t_us` (standing for `samples` samples completed then); True when it
        replaces a value nobody read."""
        with self._lock:
            self._rate.tick(t_us / 1e6, samples)
            replaced_unread = self._unread
            self._value, self._t_us, self._unread = value, t_us, True
            return replaced_unread

    def get(self) -> T | None:
        """The newest value (None before the first); marks it read."""
        with self._lock:
            self._unread = False
            return self._value

    def peek(self) -> tuple[T | None, int | None]:
        """(newest value, its t_us) without marking it read; (None, None) before the first."""
        with self._lock:
            return self._value, self._t_us

    def rate_hz(self) -> float:
        """Samples per second over the last few (0 before two)."""
        with self._lock:
            return self._rate.rate()

    def restart_rate(self) -> None:
        """Measure the rate afresh from the next sample (after a gap that should not count)."""
        with self._lock:
            self._rate.reset()

    def summary(self) -> str:
        """"30.0 Hz, age 12 ms", or "no sample yet"."""
        _, t_us = self.peek()
        if t_us is None:
            return "no sample yet"
        rate = self.rate_hz()
        return f"{f'{rate:.1f} Hz' if rate else 'rate unknown'}, age {(now_us() - t_us) / 1000:.0f} ms"


class ThreadedSource(ABC, Generic[T]):
    """Base of every live source (see the module docstring for the contract). `name` names the device in
    errors, thread names and status rows; `reconnect_backoff_s` paces the reopening of a lost device."""

    RATE_WINDOW = RATE_WINDOW

    def __init__(self, name: str, reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S) -> None:
        self.name = name
        self._backoff = check_backoff(reconnect_backoff_s, name)
        self._retry_s = self._backoff[0]
        self._down_reason: str | None = None
        self._slot: LatestSlot[T] = LatestSlot(self.RATE_WINDOW)
        self._lock = threading.Lock()
        self._counters = self._new_counters()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ended: str | None = None
        self._last_error: str | None = None

    # --- what a device implements -------------------------------------------------------------------

    def _new_counters(self) -> SourceCounters:
        """Fresh counters (a subclass of SourceCounters for a device that counts more)."""
        return SourceCounters()

    @abstractmethod
    def _open(self) -> None:
        """Open the device; raise UserError naming what is wrong. `_close` runs after a failure too."""

    @abstractmethod
    def _step(self) -> None:
        """Read (waiting at most ~0.1 s, or until `self._stop` is set) and publish at most one sample;
        raise SourceEnded when done, DeviceLost when the device went away. Any other exception is counted in
        `errors` and the reader goes on."""

    @abstractmethod
    def _close(self) -> None:
        """Release whatever `_open` got, also when it got only part of it; safe to call twice."""

    def _reopen(self) -> None:
        """Open a device that went away again, by the same stable name; raise (DeviceLost with a reason, or
        any error) while it is still away. `_close` runs after a failure too."""
        self._open()

    def _status_details(self) -> str:
        """Extra text for the end of the standard status line (", ..."), or ""."""
        return ""

    # --- the contract -------------------------------------------------------------------------------

    @property
    def is_connected(self) -> bool:
        return self._thread is not None

    def connect(self) -> None:
        """Open the device and start the reader thread (see the module docstring)."""
        if self.is_connected:
            raise DeviceAlreadyConnectedError(f"{self.name} is already connected; disconnect it first")
        self._slot, self._counters = LatestSlot(self.RATE_WINDOW), self._new_counters()
        self._ended = self._last_error = self._down_reason = None
        self._retry_s = self._backoff[0]
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
        """The newest sample, or None before the first; kept after disconnect until the next connect."""
        return self._slot.get()

    def rate_hz(self) -> float:
        """Measured samples per second over the last few samples (0 before two)."""
        return self._slot.rate_hz()

    def age_ms(self) -> float | None:
        """Milliseconds since the newest sample was captured, or None before the first."""
        _, t_us = self._slot.peek()
        return None if t_us is None else (now_us() - t_us) / 1000

    @property
    def counters(self) -> SourceCounters:
        """A consistent copy of the counters."""
        with self._lock:
            return dataclasses.replace(self._counters)

    @property
    def ended(self) -> str | None:
        """Why the reader stopped on its own (end of file, device gone), or None while it runs."""
        return self._ended

    @property
    def retrying(self) -> bool:
        """True while a device that went away is being reopened (its last sample is not current)."""
        return self._down_reason is not None

    @property
    def down_reason(self) -> str | None:
        """Why the device is away ("… vanished", "no frame for 2.0 s", the last reopen's error) while it is
        retried, else None."""
        return self._down_reason

    def status(self) -> str:
        """One line for a dashboard, e.g. "connected, 30.0 Hz, age 12 ms, 300 samples, 0 unread, 0 errors"."""
        if not self.is_connected:
            return "disconnected"
        counts = self.counters
        counters = ", ".join(f"{getattr(counts, field.name)} {field.name}" for field in dataclasses.fields(counts))
        state = f"stopped ({self._ended})" if self._ended else "connected"
        if (retrying := self._retrying_text()) is not None:
            state = retrying
        return f"{state}, {self._slot.summary()}, {counters}{self._status_details()}{self._error_suffix()}"

    def _retrying_text(self) -> str | None:
        """"disconnected, retrying (<reason>) every ≤ 2 s" while a lost device is retried, else None."""
        reason = self._down_reason
        return None if reason is None else f"disconnected, retrying ({reason}) every ≤ {self._backoff[1]:g} s"

    # --- helpers for devices ------------------------------------------------------------------------

    def _publish(self, sample: T, t_us: int, samples: int = 1, **counts: int) -> None:
        """Make `sample` (captured at host time `t_us`) the latest; it stands for `samples` samples (a read
        that completed several publishes only the newest). `counts` are added to the counters at the same
        time, so a reader never sees the sample without them."""
        replaced_unread = self._slot.put(sample, t_us, samples)
        with self._lock:
            self._counters.samples += samples
            self._counters.unread += replaced_unread
            self._add_counts(counts)

    def _count(self, **counts: int) -> None:
        """Add to the named counters, e.g. `self._count(dropped=2)`."""
        with self._lock:
            self._add_counts(counts)

    def _add_counts(self, counts: dict[str, int]) -> None:
        for name, amount in counts.items():
            setattr(self._counters, name, getattr(self._counters, name) + amount)

    def _note_error(self, exc: BaseException) -> None:
        """Count a failure (the source goes on) and keep it for the status line."""
        self._count(errors=1)
        self._last_error = f"{type(exc).__name__}: {exc}"

    def _error_suffix(self) -> str:
        """", last error: ..." when a step failed since connect, else ""."""
        return f", last error: {self._last_error}" if self._last_error else ""

    def _run(self) -> None:
        while not self._stop.is_set():
            if self._down_reason is not None:
                self._retry()
                continue
            try:
                self._step()
            except SourceEnded as end:
                self._ended = str(end)
                return
            except DeviceLost as lost:
                self._lose(str(lost) or "device lost")
            except Exception as exc:  # noqa: BLE001 - the reader must outlive a bad sample; counted and shown
                self._note_error(exc)
                self._stop.wait(ERROR_PAUSE_S)

    def _lose(self, reason: str) -> None:
        """The device went away: close it and retry from the shortest back-off."""
        self._close_quietly()
        with self._lock:
            self._down_reason, self._retry_s = reason, self._backoff[0]
        self._slot.restart_rate()

    def _retry(self) -> None:
        """Wait the back-off, then try to reopen the device; the wait doubles (up to the longest) per failure."""
        if self._stop.wait(self._retry_s):
            return
        try:
            self._reopen()
        except Exception as exc:  # noqa: BLE001 - any failure to reopen means "still away"; shown in the status
            self._close_quietly()
            with self._lock:
                self._down_reason = str(exc) or type(exc).__name__
                self._retry_s = min(2 * self._retry_s, self._backoff[1])
            return
        with self._lock:
            self._down_reason = None
            self._counters.reconnects += 1

    def _close_quietly(self) -> None:
        """`_close` of a device that is gone; what closing it raises is counted, not propagated."""
        try:
            self._close()
        except Exception as exc:  # noqa: BLE001 - a vanished device may fail to close; it is released anyway
            self._note_error(exc)
