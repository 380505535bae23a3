"""A simulated Rokoko Studio: a thread that sends LZ4-compressed JSON v3 datagrams at a steady rate.

Frame k is due at start + k / fps (an absolute schedule, so no drift accumulates). After a stall the
sender skips to the frame due now instead of sending a burst, as a live source would; skipped frames are
counted. Each datagram's scene timestamp is k / fps seconds.
"""
from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from touchanything.core.errors import UserError
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.hardware.rokoko_protocol import encode_datagram
from touchanything.devices.worker_thread import start_worker, stop_worker

HandsProvider = Callable[[int], tuple[np.ndarray, np.ndarray]]
"""frame index k → ((2, 21, 3) joints in Studio coordinates, (2,) bool hands present)."""


@dataclass(frozen=True)
class RokokoSenderConfig:
    """Where to send (Studio's default target is 127.0.0.1:14043), how often, and the actor's name."""

    host: str = "127.0.0.1"
    port: int = 14043
    fps: float = 30.0
    actor: str = "sim"


def episode_hands_provider(episode: Episode) -> HandsProvider:
    """Frame k → the episode's Rokoko hands at frame k mod its length (looping), exactly as stored."""
    hands = episode.hands("rokoko")
    if hands is None or len(hands.valid) == 0:
        raise UserError(f"{episode.path}: no Rokoko hand stream (rokoko_hands.json) to send; choose another episode")
    frames = len(hands.valid)

    def provider(index: int) -> tuple[np.ndarray, np.ndarray]:
        return hands.joints[index % frames], hands.valid[index % frames]

    return provider


class SimulatedRokokoSender:
    """Use as a context manager, or `start()` / `stop()`. Counters: `frames_sent`, `frames_skipped`,
    `send_errors` (a datagram the OS refused)."""

    def __init__(self, provider: HandsProvider, config: RokokoSenderConfig = RokokoSenderConfig()) -> None:
        if not (math.isfinite(config.fps) and config.fps > 0):
            raise UserError(f"simulated Rokoko rate must be a positive number of frames per second, got {config.fps}")
        self.provider, self.config = provider, config
        self.frames_sent = self.frames_skipped = self.send_errors = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._socket: socket.socket | None = None
        self._target: tuple = ()

    @property
    def is_running(self) -> bool:
        return self._thread is not None

    def start(self) -> None:
        """Resolve the target, open the socket and start sending; UserError for an unknown host."""
        if self.is_running:
            raise RuntimeError("the simulated Rokoko sender is already running")
        where = f"{self.config.host}:{self.config.port}"
        try:
            family, kind, proto, _, self._target = socket.getaddrinfo(
                self.config.host, self.config.port, type=socket.SOCK_DGRAM)[0]
        except (socket.gaierror, UnicodeError) as exc:
            raise UserError(f"cannot send simulated Rokoko data to {where}: unknown host ({exc})") from None
        self._socket = socket.socket(family, kind, proto)
        self._stop.clear()
        self._thread = start_worker(self._run, "rokoko-sim-sender", self._close_socket)

    def stop(self) -> None:
        """Stop and join the thread, close the socket; does nothing when not running."""
        if self._thread is None:
            return
        stop_worker(self._thread, self._stop)
        self._thread = None
        self._close_socket()

    def __enter__(self) -> SimulatedRokokoSender:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _close_socket(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None

    def _run(self) -> None:
        fps, start, index = self.config.fps, time.monotonic(), 0
        while True:
            delay = start + index / fps - time.monotonic()
            if self._stop.wait(max(delay, 0.0)):
                return
            self._send(index)
            due_now = int((time.monotonic() - start) * fps)
            self.frames_skipped += max(due_now - index - 1, 0)
            index = max(index + 1, due_now)

    def _send(self, index: int) -> None:
        joints, present = self.provider(index)
        datagram = encode_datagram(joints, present, fps=self.config.fps, timestamp=index / self.config.fps,
                                   actor=self.config.actor)
        try:
            self._socket.sendto(datagram, self._target)
        except OSError:
            self.send_errors += 1
            return
        self.frames_sent += 1
