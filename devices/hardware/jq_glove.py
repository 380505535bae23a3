"""A Juqiao (JQ) pressure glove on a serial port, as a ThreadedSource: one reader thread, a latest-value slot,
side check and reconnection with back-off when the glove is unplugged.

The port may be a stable symlink (`/dev/serial/by-id/...`); it is resolved again on every reconnect, so a
replugged glove that comes back as another `/dev/ttyACM*` is found. While the port is away the source
stays connected (`is_connected`), and the shared reader (`ThreadedSource`) retries it with back-off and
says so in its status.
"""
from __future__ import annotations

import errno
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import serial

from touchanything.core.errors import UserError
from touchanything.devices.hardware.jq_protocol import SIDE_SENSORS, JQParserCounters, JQSample, JQStreamParser
from touchanything.devices.hardware.threaded_source import (
    DEFAULT_BACKOFF_S,
    DeviceLost,
    SourceCounters,
    ThreadedSource,
    check_backoff,
    now_us,
)

SERIAL_BY_ID = Path("/dev/serial/by-id")
OTHER_SIDE_GRACE_US = 1_000_000
"""The swap-ports message shows while the other hand arrived in the last second and this one did not."""
SERIAL_ERRORS = (serial.SerialException, OSError, ValueError)
"""What opening or reading a port raises when it is absent, unplugged or not a serial device."""


@dataclass(frozen=True)
class JQGloveConfig:
    """port: device path or any symlink to it. side: the hand this port should carry ("left"/"right").

    read_timeout_s: longest a read blocks (bounds how fast `disconnect` returns).
    reconnect_backoff_s: (first wait, longest wait) between attempts to reopen a lost port; the wait
    doubles after every failed attempt. Any two-item sequence is accepted (TOML gives a list).
    """

    port: str
    side: str
    baudrate: int = 921600
    read_timeout_s: float = 0.02
    reconnect_backoff_s: tuple[float, float] = DEFAULT_BACKOFF_S

    def __post_init__(self) -> None:
        if self.side not in SIDE_SENSORS:
            raise UserError(f"glove side must be left or right, got {self.side!r}")
        if not self.baudrate > 0:
            raise UserError(f"glove baud rate must be positive, got {self.baudrate}")
        if not (self.read_timeout_s > 0 and math.isfinite(self.read_timeout_s)):
            raise UserError(f"glove read timeout must be a positive number of seconds, got {self.read_timeout_s}")
        object.__setattr__(self, "reconnect_backoff_s", check_backoff(self.reconnect_backoff_s, "glove"))


@dataclass(frozen=True)
class GloveReading:
    """The newest sample: raw (256,) uint8 and quat_wxyz (4,) float32 (all NaN if invalid), both read-only;
    side as the glove reports it; t_us host monotonic µs of the read that completed the sample."""

    side: str
    raw: np.ndarray
    quat_wxyz: np.ndarray
    t_us: int


@dataclass
class JQGloveCounters(SourceCounters):
    """Totals since `connect`: samples of this side (published), samples of the other hand (not published),
    reopenings of a lost port (`reconnects`, from the base), and the parser's own counters (a copy)."""

    other_side_samples: int = 0
    parser: JQParserCounters = field(default_factory=JQParserCounters)


def serial_devices_hint(by_id: Path = SERIAL_BY_ID) -> str:
    """One phrase listing what is plugged in under /dev/serial/by-id."""
    names = sorted(p.name for p in by_id.iterdir()) if by_id.is_dir() else []
    if not names:
        return f"there is nothing under {by_id} (is the glove plugged in?)"
    return f"under {by_id} there is: {', '.join(names)}"


def open_port(port: str, baudrate: int, timeout_s: float) -> tuple[serial.Serial, str]:
    """Resolve the port's symlinks and open it; raises one of SERIAL_ERRORS on failure."""
    path = os.path.realpath(port)
    return serial.Serial(path, baudrate, timeout=timeout_s), path


def open_failure(port: str, exc: BaseException) -> str:
    """Why a port could not be opened, as one phrase with a hint when the user can fix it."""
    hint = "; add your user to the dialout group" if getattr(exc, "errno", None) == errno.EACCES else ""
    return f"{exc}{hint}"


class JQGlove(ThreadedSource[GloveReading]):
    """One glove on one port. `latest()` is the newest sample of this side (kept across an unplug: judge it
    by `t_us`); `status()` is one dashboard line (connected, retrying, or the wrong glove on this port)."""

    RATE_WINDOW = 100

    def __init__(self, config: JQGloveConfig) -> None:
        super().__init__(f"{config.side} glove on {config.port}", config.reconnect_backoff_s)
        self.config = config
        self._parser = JQStreamParser()
        self._port: serial.Serial | None = None
        self._path = ""
        self._last_other_side_us: int | None = None

    def _new_counters(self) -> JQGloveCounters:
        return JQGloveCounters()

    @property
    def counters(self) -> JQGloveCounters:
        return super().counters  # type: ignore[return-value]

    def _open(self) -> None:
        """Open the port; UserError when it is absent or cannot be opened."""
        port = self.config.port
        if not os.path.exists(port):
            raise UserError(f"glove port {port} does not exist; {serial_devices_hint()}")
        try:
            self._port, self._path = open_port(port, self.config.baudrate, self.config.read_timeout_s)
        except SERIAL_ERRORS as exc:
            raise UserError(f"cannot open glove port {port}: {open_failure(port, exc)}") from None
        self._parser = JQStreamParser()
        self._last_other_side_us = None

    def _step(self) -> None:
        """Read what is waiting (at least one byte, up to the read timeout), parse, publish; a failed read
        means the port went away (DeviceLost)."""
        try:
            data = self._port.read(self._port.in_waiting or 1)
        except SERIAL_ERRORS as exc:
            raise DeviceLost(self._failure(exc)) from None
        if data:
            self._take(self._parser.feed(data), now_us())

    def _close(self) -> None:
        if self._port is not None:
            self._port.close()
        self._port = None

    def _failure(self, exc: Exception) -> str:
        """"<port>: port not present", or the port and what opening or reading it raised."""
        why = "port not present" if not os.path.exists(self.config.port) else str(exc) or type(exc).__name__
        return f"{self.config.port}: {why}"

    def _reopen(self) -> None:
        """Open the port again (its symlink resolved anew) and start the parser over; DeviceLost while away."""
        try:
            port, path = open_port(self.config.port, self.config.baudrate, self.config.read_timeout_s)
        except SERIAL_ERRORS as exc:
            raise DeviceLost(self._failure(exc)) from None
        self._parser.reset()
        self._port = port
        with self._lock:
            self._path = path

    def _take(self, samples: list[JQSample], t_us: int) -> None:
        """Publish the newest sample of this side; count the other side's."""
        own = [s for s in samples if s.side == self.config.side]
        other = len(samples) - len(own)
        if other:
            self._last_other_side_us = t_us
        with self._lock:
            self._counters.parser = replace(self._parser.counters)
        if own:
            newest = own[-1]
            reading = GloveReading(newest.side, newest.raw, newest.quat_wxyz, t_us)
            self._publish(reading, t_us, samples=len(own), other_side_samples=other)
        elif other:
            self._count(other_side_samples=other)

    def status(self) -> str:
        """One line: connected (rate, age, resyncs), retrying a lost port, wrong glove on this port, or
        disconnected."""
        if not self.is_connected:
            return "disconnected"
        port, counters = self.config.port, self.counters
        with self._lock:
            path = self._path
        if (retrying := self._retrying_text()) is not None:
            return f"{retrying}, {counters.reconnects} reconnects"
        age_ms, other_us = self.age_ms(), self._last_other_side_us
        own_stale = age_ms is None or age_ms * 1000 > OTHER_SIDE_GRACE_US
        if other_us is not None and now_us() - other_us < OTHER_SIDE_GRACE_US and own_stale:
            other = next(side for side in SIDE_SENSORS if side != self.config.side)
            return f"port {port} carries the {other} glove; swap ports in the scene file"
        where = path if path == port else f"{port} → {path}"
        if age_ms is None:
            return f"connected {where}, no sample yet"
        rate = self.rate_hz()
        rate_text = f"{rate:.0f} Hz" if rate else "measuring rate"
        return (f"connected {where}, {rate_text}, age {age_ms:.0f} ms, {counters.parser.resyncs} resyncs, "
                f"{counters.reconnects} reconnects{self._error_suffix()}")
