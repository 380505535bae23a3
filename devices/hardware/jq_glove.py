"""A Juqiao (JQ) pressure glove on a serial port: one reader thread, a latest-value slot, side check and
reconnection with back-off when the glove is unplugged.

The port may be a stable symlink (`/dev/serial/by-id/...`); it is resolved again on every reconnect, so a
replugged glove that comes back as another `/dev/ttyACM*` is found.
"""
from __future__ import annotations

import errno
import math
import os
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import serial

from touchanything.devices.errors import UserError
from touchanything.devices.hardware.jq_protocol import SIDE_SENSORS, JQParserCounters, JQSample, JQStreamParser
from touchanything.devices.worker_thread import start_worker, stop_worker

SERIAL_BY_ID = Path("/dev/serial/by-id")
RATE_WINDOW_US = 1_000_000
OTHER_SIDE_GRACE_US = 1_000_000
"""The swap-ports message shows while the other hand arrived in the last second and this one did not."""


@dataclass(frozen=True)
class JQGloveConfig:
    """port: device path or any symlink to it. side: the hand this port should carry ("left"/"right").

    read_timeout_s: longest a read blocks (bounds how fast `disconnect` returns).
    reconnect_backoff_s: (first wait, longest wait) between attempts to reopen a lost port; the wait
    doubles after every failed attempt.
    """

    port: str
    side: str
    baudrate: int = 921600
    read_timeout_s: float = 0.02
    reconnect_backoff_s: tuple[float, float] = (0.1, 2.0)

    def __post_init__(self) -> None:
        if self.side not in SIDE_SENSORS:
            raise UserError(f"glove side must be left or right, got {self.side!r}")
        if not self.baudrate > 0:
            raise UserError(f"glove baud rate must be positive, got {self.baudrate}")
        if not (self.read_timeout_s > 0 and math.isfinite(self.read_timeout_s)):
            raise UserError(f"glove read timeout must be a positive number of seconds, got {self.read_timeout_s}")
        first, longest = self.reconnect_backoff_s
        if not (0 < first <= longest and math.isfinite(longest)):
            raise UserError("glove reconnect back-off must be (first, longest) seconds with 0 < first <= longest, "
                            f"got {self.reconnect_backoff_s}")


@dataclass(frozen=True)
class GloveReading:
    """The newest sample: raw (256,) uint8 and quat_wxyz (4,) float32 (all NaN if invalid), both read-only;
    side as the glove reports it; t_us host monotonic µs of the read that completed the sample."""

    side: str
    raw: np.ndarray
    quat_wxyz: np.ndarray
    t_us: int


@dataclass(frozen=True)
class JQGloveCounters:
    """Totals since `connect`: samples published, samples of the other hand (not published), reopenings
    of a lost port, and the parser's own counters."""

    samples: int
    other_side_samples: int
    reconnects: int
    parser: JQParserCounters


def serial_devices_hint() -> str:
    """One phrase listing what is plugged in under /dev/serial/by-id."""
    names = sorted(p.name for p in SERIAL_BY_ID.iterdir()) if SERIAL_BY_ID.is_dir() else []
    if not names:
        return f"there is nothing under {SERIAL_BY_ID} (is the glove plugged in?)"
    return f"under {SERIAL_BY_ID} there is: {', '.join(names)}"


def open_port(config: JQGloveConfig) -> tuple[serial.Serial, str]:
    """Resolve the port's symlinks and open it; raises serial.SerialException (or OSError) on failure."""
    path = os.path.realpath(config.port)
    return serial.Serial(path, config.baudrate, timeout=config.read_timeout_s), path


class JQGlove:
    """One glove on one port. `connect()` opens the port and starts the reader; `latest()` is the newest
    sample of this side (kept across an unplug: judge it by `t_us`); `status()` is one dashboard line."""

    def __init__(self, config: JQGloveConfig) -> None:
        self.config = config
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset_state()

    def _reset_state(self) -> None:
        self._parser = JQStreamParser()
        self._latest: GloveReading | None = None
        self._samples = self._other_side = self._reconnects = 0
        self._parser_counters = JQParserCounters()
        self._last_other_side_us: int | None = None
        self._window_start_us: int | None = None
        self._window_samples = 0
        self._rate_hz = 0.0
        self._path = ""
        self._down_reason: str | None = None
        self._retry_s = self.config.reconnect_backoff_s[0]

    @property
    def is_connected(self) -> bool:
        """True between connect and disconnect (also while an unplugged port is being retried)."""
        return self._thread is not None

    def connect(self) -> None:
        """Open the port and start the reader thread; UserError if the port is absent or cannot be opened."""
        if self._thread is not None:
            raise RuntimeError(f"glove on {self.config.port} is already connected")
        if not os.path.exists(self.config.port):
            raise UserError(f"glove port {self.config.port} does not exist; {serial_devices_hint()}")
        try:
            port, path = open_port(self.config)
        except (serial.SerialException, OSError, ValueError) as exc:
            hint = "; add your user to the dialout group" if getattr(exc, "errno", None) == errno.EACCES else ""
            raise UserError(f"cannot open glove port {self.config.port}: {exc}{hint}") from None
        self._reset_state()
        self._path = path
        self._stop.clear()
        self._thread = start_worker(lambda: self._read_loop(port), f"jq-glove-{self.config.side}", port.close)

    def disconnect(self) -> None:
        """Stop the reader (returns within about one read timeout) and close the port."""
        stop_worker(self._thread, self._stop)
        self._thread = None

    def __enter__(self) -> JQGlove:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.disconnect()

    def latest(self) -> GloveReading | None:
        """The newest sample of this side, or None before the first one."""
        with self._lock:
            return self._latest

    @property
    def counters(self) -> JQGloveCounters:
        """A consistent copy of the counters."""
        with self._lock:
            return JQGloveCounters(self._samples, self._other_side, self._reconnects, self._parser_counters)

    def status(self) -> str:
        """One line: connected (rate, age, resyncs), waiting, wrong glove on this port, or disconnected."""
        port, now_us = self.config.port, time.monotonic_ns() // 1000
        with self._lock:
            latest, reason, path = self._latest, self._down_reason, self._path
            other_us, rate, reconnects = self._last_other_side_us, self._rate_hz, self._reconnects
            resyncs = self._parser_counters.resyncs
        if self._thread is None:
            return "not connected"
        if reason is not None:
            return (f"disconnected: {port} ({reason}); retrying every ≤ {self.config.reconnect_backoff_s[1]:g} s, "
                    f"{reconnects} reconnects")
        own_stale = latest is None or now_us - latest.t_us > OTHER_SIDE_GRACE_US
        if other_us is not None and now_us - other_us < OTHER_SIDE_GRACE_US and own_stale:
            other = next(side for side in SIDE_SENSORS if side != self.config.side)
            return f"port {port} carries the {other} glove; swap ports in the scene file"
        where = path if path == port else f"{port} → {path}"
        if latest is None:
            return f"connected {where}, no sample yet"
        rate_text = f"{rate:.0f} Hz" if rate else "measuring rate"
        return (f"connected {where}, {rate_text}, age {(now_us - latest.t_us) // 1000} ms, "
                f"{resyncs} resyncs, {reconnects} reconnects")

    def _read_loop(self, port: serial.Serial | None) -> None:
        """Reader thread: read what is waiting (at least one byte, up to the read timeout), parse, publish."""
        try:
            while not self._stop.is_set():
                if port is None:
                    port = self._reopen()
                    continue
                try:
                    data = port.read(port.in_waiting or 1)
                except (serial.SerialException, OSError) as exc:
                    port.close()
                    port = None
                    self._lost(exc)
                    continue
                t_us = time.monotonic_ns() // 1000
                if data:
                    self._publish(self._parser.feed(data), t_us)
        finally:
            if port is not None:
                port.close()

    def _failure(self, exc: Exception) -> str:
        return "port not present" if not os.path.exists(self.config.port) else str(exc) or type(exc).__name__

    def _lost(self, exc: Exception) -> None:
        reason = self._failure(exc)
        with self._lock:
            self._down_reason, self._retry_s = reason, self.config.reconnect_backoff_s[0]
            self._window_start_us, self._window_samples, self._rate_hz = None, 0, 0.0

    def _reopen(self) -> serial.Serial | None:
        """Wait the back-off, then try the port again (its symlink resolved anew)."""
        if self._stop.wait(self._retry_s):
            return None
        try:
            port, path = open_port(self.config)
        except (serial.SerialException, OSError, ValueError) as exc:
            reason = self._failure(exc)
            with self._lock:
                self._down_reason = reason
                self._retry_s = min(2 * self._retry_s, self.config.reconnect_backoff_s[1])
            return None
        self._parser.reset()
        with self._lock:
            self._path, self._down_reason, self._reconnects = path, None, self._reconnects + 1
        return port

    def _publish(self, samples: list[JQSample], t_us: int) -> None:
        own = [s for s in samples if s.side == self.config.side]
        with self._lock:
            self._parser_counters = replace(self._parser.counters)
            if len(own) < len(samples):
                self._other_side += len(samples) - len(own)
                self._last_other_side_us = t_us
            if own:
                newest = own[-1]
                self._latest = GloveReading(newest.side, newest.raw, newest.quat_wxyz, t_us)
                self._samples += len(own)
                self._count_rate(len(own), t_us)

    def _count_rate(self, samples: int, t_us: int) -> None:
        """Samples per second over windows of at least one second (call with the lock held)."""
        if self._window_start_us is None:
            self._window_start_us = t_us
            return
        self._window_samples += samples
        elapsed = t_us - self._window_start_us
        if elapsed >= RATE_WINDOW_US:
            self._rate_hz = self._window_samples * 1e6 / elapsed
            self._window_start_us, self._window_samples = t_us, 0
