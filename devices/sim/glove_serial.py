"""A simulated JQ pressure glove on a pseudo-terminal: the real byte stream at the real cadence, behind a
stable symlink (as under /dev/serial/by-id), with unplug, replug and byte injection for tests."""
from __future__ import annotations

import math
import os
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.snapshot import HANDS
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.hardware.jq_protocol import FIRST_HALF, PACKET_BYTES, encode_sample, sensor_type

SampleProvider = Callable[[int], tuple[np.ndarray, np.ndarray]]
"""Sample index → (raw (256,) uint8, quat_wxyz (4,) float32)."""
SAMPLE_RATE_HZ = 100
PACKET_PERIOD_S = 1 / (2 * SAMPLE_RATE_HZ)
"""Packets 01 and 02 each at 100 Hz, evenly spaced: one packet every 5 ms."""


class SimulatedGloveSerial:
    """One glove streaming into a pty from a background thread, started on construction.

    Packet j is due at start + j · 5 ms (absolute schedule: a late packet goes out at once and the next
    ones catch up, so no drift builds up); sample k = provider(k) is packets 2k and 2k + 1.
    `path` is a symlink in `link_dir` (an existing folder) to the current pty slave. Writes never block:
    bytes that do not fit in the pty (nobody reading) are lost, as a USB device loses what the host does
    not fetch.
    """

    def __init__(self, side: str, provider: SampleProvider, link_dir: Path, link_name: str | None = None) -> None:
        sensor_type(side)
        self.side, self._provider = side, provider
        self.path = Path(link_dir) / (link_name or f"usb-Juqiao_JQ_glove_{side}-if00")
        self._lock = threading.Lock()
        self._master: int | None = None
        self._slave: int | None = None
        self._stop = threading.Event()
        self.replug()
        self._thread = threading.Thread(target=self._stream, daemon=True, name=f"sim-jq-glove-{side}")
        self._thread.start()

    def replug(self) -> None:
        """Open a new pty pair (in raw mode, no echo) and point the symlink at its slave."""
        with self._lock:
            if self._master is not None:
                return
            master, slave = os.openpty()
            try:
                tty.setraw(slave)
                os.set_blocking(master, False)
                temporary = self.path.with_name(self.path.name + ".new")
                temporary.unlink(missing_ok=True)
                temporary.symlink_to(os.ttyname(slave))
                os.replace(temporary, self.path)
            except OSError:
                os.close(master)
                os.close(slave)
                raise
            self._master, self._slave = master, slave

    def unplug(self) -> None:
        """Close both ends of the pty (a reader sees an I/O error) and remove the symlink."""
        with self._lock:
            if self._master is None:
                return
            os.close(self._master)
            os.close(self._slave)
            self._master = self._slave = None
            self.path.unlink(missing_ok=True)

    def inject(self, data: bytes) -> None:
        """Put bytes on the line now, as if the glove sent them (what does not fit is lost)."""
        with self._lock:
            if self._master is None:
                return
            try:
                os.write(self._master, data)
            except BlockingIOError:
                pass

    def close(self) -> None:
        """Stop streaming and unplug."""
        self._stop.set()
        self._thread.join()
        self.unplug()

    def __enter__(self) -> SimulatedGloveSerial:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _stream(self) -> None:
        start, packet, sample = time.monotonic(), 0, b""
        split = PACKET_BYTES[FIRST_HALF]
        while not self._stop.wait(max(0.0, start + packet * PACKET_PERIOD_S - time.monotonic())):
            if packet % 2 == 0:
                sample = encode_sample(self.side, *self._provider(packet // 2))
                self.inject(sample[:split])
            else:
                self.inject(sample[split:])
            packet += 1


def episode_glove_provider(episode: Episode, side: str) -> SampleProvider:
    """Samples at 100 Hz from an episode's glove stream for one hand: sample i is frame
    floor(i · fps / 100), looping over the episode."""
    glove = episode.glove
    if glove is None or len(glove.raw) == 0:
        raise UserError(f"{episode.path}: the episode has no glove stream to simulate")
    hand = HANDS.index(side)
    raw, quat = glove.raw[:, hand], glove.quat_wxyz[:, hand].astype(np.float32)

    def sample(index: int) -> tuple[np.ndarray, np.ndarray]:
        frame = math.floor(index * episode.fps / SAMPLE_RATE_HZ) % len(raw)
        return raw[frame], quat[frame]

    return sample
