"""Rokoko Studio hand mocap over UDP: a reader thread keeps the latest decoded hands of one actor.

Studio sends one datagram per frame (Livestreaming → Custom streaming, JSON v3, default port 14043).
Every datagram is counted; oversized and malformed ones are dropped and counted, never raised. A datagram
with no hand present still replaces the latest reading (the hands are gone) and is counted as `no_hand`.
"""
from __future__ import annotations

import dataclasses
import socket
import threading
import time
from collections import deque
from dataclasses import dataclass

from touchanything.devices.errors import UserError
from touchanything.devices.hardware.rokoko_protocol import RokokoFrame, RokokoProtocolError, decode_datagram
from touchanything.devices.snapshot import HANDS
from touchanything.devices.worker_thread import start_worker, stop_worker

UDP_MAX_PAYLOAD = 65507
"""The largest UDP payload over IPv4."""
MIN_RECEIVE_BUFFER = 80 * 1024
RATE_WINDOW = 32
"""Decoded datagrams over which the rate is estimated."""


@dataclass(frozen=True)
class RokokoConfig:
    """host: local address to listen on ("0.0.0.0" for Studio on another machine); port 0 picks a free one.

    actor: Studio actor name to follow; None follows the first actor with a glove.
    max_datagram_bytes: larger datagrams are dropped (counted as oversized).
    socket_buffer_bytes: SO_RCVBUF requested from the kernel (it may grant less).
    poll_s: receive timeout, which bounds how long `disconnect` waits for the thread.
    """

    host: str = "127.0.0.1"
    port: int = 14043
    actor: str | None = None
    max_datagram_bytes: int = UDP_MAX_PAYLOAD
    socket_buffer_bytes: int = 4 * 1024 * 1024
    poll_s: float = 0.1


@dataclass(frozen=True)
class RokokoReading:
    """A decoded frame and its host capture time `t_us` (time.monotonic_ns() // 1000 at reception)."""

    frame: RokokoFrame
    t_us: int


@dataclass
class RokokoCounters:
    """datagrams: all received; decoded: usable (no_hand of them without any hand present); malformed and
    oversized: dropped."""

    datagrams: int = 0
    decoded: int = 0
    malformed: int = 0
    oversized: int = 0
    no_hand: int = 0


def check_config(config: RokokoConfig) -> None:
    """One clear UserError per bad option."""
    if not 0 <= config.port <= 65535:
        raise UserError(f"Rokoko UDP port {config.port} is out of range; choose 0–65535 (Studio sends to 14043)")
    if not 1 <= config.max_datagram_bytes <= UDP_MAX_PAYLOAD:
        raise UserError(f"Rokoko max datagram size {config.max_datagram_bytes} must be 1–{UDP_MAX_PAYLOAD} bytes")
    if not config.poll_s > 0:
        raise UserError(f"Rokoko receive poll time must be positive, got {config.poll_s}")


def bind_socket(config: RokokoConfig) -> socket.socket:
    """A UDP socket bound to host:port with the configured buffer and timeout; UserError when impossible."""
    where = f"cannot listen for Rokoko Studio on UDP {config.host}:{config.port}"
    try:
        family, kind, proto, _, address = socket.getaddrinfo(
            config.host, config.port, type=socket.SOCK_DGRAM, flags=socket.AI_PASSIVE)[0]
    except (socket.gaierror, UnicodeError) as exc:
        raise UserError(f"{where}: unknown host ({exc}); check the host address") from None
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, config.socket_buffer_bytes)
        sock.settimeout(config.poll_s)
        sock.bind(address)
    except OSError as exc:
        sock.close()
        raise UserError(f"{where}: {exc.strerror or exc}; choose a local address and a free port "
                        "(Studio: Livestreaming → Custom streaming) or stop the program using it") from None
    return sock


class RokokoReceiver:
    """Listens for Rokoko Studio datagrams. Use as a context manager, or `connect()` / `disconnect()`."""

    def __init__(self, config: RokokoConfig = RokokoConfig()) -> None:
        self.config = config
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._socket: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._latest: RokokoReading | None = None
        self._counters = RokokoCounters()
        self._arrivals: deque[int] = deque(maxlen=RATE_WINDOW)
        self._last_problem = ""

    @property
    def is_connected(self) -> bool:
        return self._thread is not None

    @property
    def bound_address(self) -> tuple[str, int]:
        """The (host, port) actually listened on (the chosen port when port 0 was requested)."""
        if self._socket is None:
            raise RuntimeError("the Rokoko receiver is not connected")
        host, port = self._socket.getsockname()[:2]
        return host, port

    def connect(self) -> None:
        """Bind the socket and start the reader thread; UserError for a bad option or a busy/bad address."""
        if self.is_connected:
            raise RuntimeError("the Rokoko receiver is already connected")
        check_config(self.config)
        self._socket = bind_socket(self.config)
        self._stop.clear()
        self._thread = start_worker(self._run, "rokoko-udp", self._close_socket)

    def disconnect(self) -> None:
        """Stop and join the reader thread, close the socket; does nothing when not connected."""
        if self._thread is None:
            return
        stop_worker(self._thread, self._stop)
        self._thread = None
        self._close_socket()

    def __enter__(self) -> RokokoReceiver:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.disconnect()

    def latest(self) -> RokokoReading | None:
        """The newest decoded reading, or None before the first one."""
        with self._lock:
            return self._latest

    @property
    def counters(self) -> RokokoCounters:
        """A consistent copy of the counters."""
        with self._lock:
            return dataclasses.replace(self._counters)

    def rate_hz(self) -> float:
        """Decoded datagrams per second over the last few (0 before two have arrived)."""
        with self._lock:
            if len(self._arrivals) < 2 or self._arrivals[-1] == self._arrivals[0]:
                return 0.0
            return (len(self._arrivals) - 1) * 1e6 / (self._arrivals[-1] - self._arrivals[0])

    def status(self) -> str:
        """One short line for a dashboard, e.g. "connected, 30 Hz, age 12 ms, hands left+right, 0 dropped"."""
        if not self.is_connected:
            return "disconnected"
        reading, counters, problem = self.latest(), self.counters, self._last_problem
        dropped = counters.malformed + counters.oversized
        tail = f"{dropped} dropped" + (f", last problem: {problem}" if problem else "")
        if reading is None:
            host, port = self.bound_address
            return f"listening on {host}:{port}, no data yet, {tail}"
        age_ms = (time.monotonic_ns() // 1000 - reading.t_us) / 1000
        hands = "+".join(h for h, p in zip(HANDS, reading.frame.hands_present) if p) or "none"
        return f"connected, {self.rate_hz():.0f} Hz, age {age_ms:.0f} ms, hands {hands}, {tail}"

    def _close_socket(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def _run(self) -> None:
        sock = self._socket
        buffer = bytearray(max(MIN_RECEIVE_BUFFER, self.config.max_datagram_bytes + 1))
        view = memoryview(buffer)
        while not self._stop.is_set():
            try:
                size = sock.recv_into(buffer)
            except TimeoutError:
                continue
            except OSError as exc:
                self._last_problem = f"receive error: {exc.strerror or exc}"
                self._stop.wait(self.config.poll_s)
                continue
            self._handle(bytes(view[:size]), time.monotonic_ns() // 1000)

    def _handle(self, data: bytes, t_us: int) -> None:
        """Count one datagram and keep it as the latest reading when it decodes."""
        oversized = len(data) > self.config.max_datagram_bytes
        frame, problem = None, f"datagram larger than {self.config.max_datagram_bytes} bytes"
        if not oversized:
            try:
                frame = decode_datagram(data, self.config.actor)
            except RokokoProtocolError as exc:
                problem = exc.reason
        with self._lock:
            counters = self._counters
            counters.datagrams += 1
            if frame is None:
                counters.oversized += oversized
                counters.malformed += not oversized
                self._last_problem = problem
                return
            counters.decoded += 1
            counters.no_hand += not frame.hands_present.any()
            self._latest = RokokoReading(frame, t_us)
            self._arrivals.append(t_us)
