"""Rokoko Studio hand mocap over UDP, as a ThreadedSource: a reader thread keeps the latest decoded hands
of one actor.

Studio sends one datagram per frame (Livestreaming → Custom streaming, JSON v3, default port 14043).
Every datagram is counted; oversized and malformed ones are dropped and counted, never raised. A datagram
with no hand present still replaces the latest reading (the hands are gone) and is counted as `no_hand`.
"""
from __future__ import annotations

import socket
from dataclasses import dataclass

from touchanything.core.errors import DeviceNotConnectedError, UserError
from touchanything.core.snapshot import HANDS
from touchanything.devices.hardware.rokoko_protocol import RokokoFrame, RokokoProtocolError, decode_datagram
from touchanything.devices.hardware.threaded_source import SourceCounters, ThreadedSource, now_us

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

    def __post_init__(self) -> None:
        """One clear UserError per bad option, when the config is made (a scene file is read)."""
        if not 0 <= self.port <= 65535:
            raise UserError(f"Rokoko UDP port {self.port} is out of range; choose 0–65535 (Studio sends to 14043)")
        if not 1 <= self.max_datagram_bytes <= UDP_MAX_PAYLOAD:
            raise UserError(f"Rokoko max datagram size {self.max_datagram_bytes} must be 1–{UDP_MAX_PAYLOAD} bytes")
        if not self.poll_s > 0:
            raise UserError(f"Rokoko receive poll time must be positive, got {self.poll_s}")


@dataclass(frozen=True)
class RokokoReading:
    """A decoded frame and its host capture time `t_us` (`now_us()` at reception)."""

    frame: RokokoFrame
    t_us: int


@dataclass
class RokokoCounters(SourceCounters):
    """datagrams: all received; samples: usable, published (no_hand of them without any
    hand present); malformed and oversized: dropped."""

    datagrams: int = 0
    malformed: int = 0
    oversized: int = 0
    no_hand: int = 0


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


class RokokoReceiver(ThreadedSource[RokokoReading]):
    """Listens for Rokoko Studio datagrams (the ThreadedSource contract); `bound_address` says where."""

    RATE_WINDOW = RATE_WINDOW

    def __init__(self, config: RokokoConfig = RokokoConfig()) -> None:
        super().__init__("Rokoko receiver")
        self.config = config
        self._socket: socket.socket | None = None
        self._buffer = bytearray()
        self._last_problem = ""

    def _new_counters(self) -> RokokoCounters:
        return RokokoCounters()

    @property
    def counters(self) -> RokokoCounters:
        return super().counters  # type: ignore[return-value]

    @property
    def bound_address(self) -> tuple[str, int]:
        """The (host, port) actually listened on (the chosen port when port 0 was requested);
        DeviceNotConnectedError when not connected."""
        sock = self._socket
        if sock is None:
            raise DeviceNotConnectedError(f"{self.name} is not connected; connect it to bind its UDP port")
        host, port = sock.getsockname()[:2]
        return host, port

    def _open(self) -> None:
        """Bind the socket; UserError for a busy or bad address."""
        self._buffer = bytearray(max(MIN_RECEIVE_BUFFER, self.config.max_datagram_bytes + 1))
        self._last_problem = ""
        self._socket = bind_socket(self.config)

    def _step(self) -> None:
        """Wait up to `poll_s` for one datagram and handle it (a receive error is counted by the base)."""
        try:
            size = self._socket.recv_into(self._buffer)
        except TimeoutError:
            return
        self._handle(bytes(memoryview(self._buffer)[:size]), now_us())

    def _close(self) -> None:
        if self._socket is not None:
            self._socket.close()
        self._socket = None

    def _handle(self, data: bytes, t_us: int) -> None:
        """Count one datagram and keep it as the latest reading when it decodes."""
        oversized = len(data) > self.config.max_datagram_bytes
        frame, problem = None, f"datagram larger than {self.config.max_datagram_bytes} bytes"
        if not oversized:
            try:
                frame = decode_datagram(data, self.config.actor)
            except RokokoProtocolError as exc:
                problem = exc.reason
        if frame is None:
            self._last_problem = problem
            self._count(datagrams=1, oversized=int(oversized), malformed=int(not oversized))
            return
        no_hand = int(not frame.hands_present.any())
        self._publish(RokokoReading(frame, t_us), t_us, datagrams=1, no_hand=no_hand)

    def status(self) -> str:
        """One short line for a dashboard, e.g. "connected, 30 Hz, age 12 ms, hands left+right, 0 dropped"."""
        if not self.is_connected:
            return "disconnected"
        (reading, _), counters, problem = self._slot.peek(), self.counters, self._last_problem
        dropped = counters.malformed + counters.oversized
        tail = f"{dropped} dropped" + (f", last problem: {problem}" if problem else "") + self._error_suffix()
        if reading is None:
            host, port = self.bound_address
            return f"listening on {host}:{port}, no data yet, {tail}"
        hands = "+".join(h for h, p in zip(HANDS, reading.frame.hands_present) if p) or "none"
        return f"connected, {self.rate_hz():.0f} Hz, age {self.age_ms():.0f} ms, hands {hands}, {tail}"
