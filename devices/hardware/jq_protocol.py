"""The Juqiao (JQ) pressure-glove serial protocol: packet encoding and a cadence-locked stream parser.

Pure byte handling, no I/O. Wire format (see shared/reference/devices.md):
- every packet starts with the sync `AA 55 03 99`, then the packet order (byte 4) and the sensor type
  (byte 5: 1 left hand, 2 right hand; 3–5 feet and whole body);
- packet 01 (134 bytes) carries raw slots 0–127, packet 02 (150 bytes) slots 128–255 and then the IMU
  quaternion as 4 little-endian float32 in the order w, x, y, z;
- each packet type arrives at 100 Hz per glove.

Framing: a naive sync search is fooled by pressure bytes that happen to read `AA 55 03 99`, so a packet
counts only once the next sync is seen exactly where the packet ends (+134 after a 01, +150 after a 02).
While packets line up the parser stays locked and never searches inside payloads. When a packet does not
line up (garbage, lost or inserted bytes), the lock is lost, the pending first halves are forgotten and
the parser searches for the next sync that is confirmed the same way. A packet locked onto after skipped
bytes only re-establishes the lock and is not used: a false sync inside a payload can be confirmed by a
real sync that follows it, and this rule keeps such a packet out of every sample (a wrong sample would
need two planted syncs exactly one packet apart). Only a stream that starts with a sync uses its first
packet.

Latency: confirming a packet needs its successor's sync, so the newest packet is released one packet
late: 5 ms at 200 packets/s (one glove, 01 and 02 evenly spaced).

Limits of the protocol, not of the parser: there is no checksum and no sequence number, so a bit error
inside a payload, or the loss of exactly whole packets, passes undetected.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SYNC = b"\xaa\x55\x03\x99"
HEADER_BYTES = 6
HALF_SLOTS = 128
RAW_SLOTS = 2 * HALF_SLOTS
FIRST_HALF, SECOND_HALF = 0x01, 0x02
PACKET_BYTES = {FIRST_HALF: HEADER_BYTES + HALF_SLOTS, SECOND_HALF: HEADER_BYTES + HALF_SLOTS + 16}
"""Packet length by packet order: 134 and 150."""
SENSOR_SIDES = {0x01: "left", 0x02: "right"}
SIDE_SENSORS = {side: sensor for sensor, side in SENSOR_SIDES.items()}
MAX_BUFFERED = max(PACKET_BYTES.values()) + len(SYNC) - 1
"""The parser never keeps more than this many bytes between feeds (153)."""
INVALID_QUATERNION = np.full(4, np.nan, np.float32)
INVALID_QUATERNION.flags.writeable = False


@dataclass(frozen=True)
class JQSample:
    """One glove sample.

    side: "left" or "right", as the glove reports it (sensor type byte).
    raw: (256,) uint8, read-only; slots 0–127 from packet 01, 128–255 from packet 02.
    quat_wxyz: (4,) float32, read-only, IMU orientation w, x, y, z; all NaN when the glove sent a
        non-finite value (the pressure is kept).
    """

    side: str
    raw: np.ndarray
    quat_wxyz: np.ndarray


@dataclass
class JQParserCounters:
    """Running totals since the parser was created (Python ints: they never overflow).

    packets: packets confirmed by the next sync. dropped_packets: confirmed packets not used (a 02 with
    no pending 01 of its sensor, a 01 replaced or forgotten before its 02, the packet that re-establishes
    the lock after skipped bytes). discarded_bytes: bytes outside confirmed packets. resyncs: times the
    lock was lost. other_sensor_packets: framed packets of feet/body (or unknown) sensor types, ignored.
    """

    bytes_in: int = 0
    packets: int = 0
    samples: int = 0
    resyncs: int = 0
    dropped_packets: int = 0
    discarded_bytes: int = 0
    other_sensor_packets: int = 0
    invalid_quaternions: int = 0


def sensor_type(side: str) -> int:
    """The sensor-type byte of a hand: 1 for "left", 2 for "right"."""
    if side not in SIDE_SENSORS:
        raise ValueError(f"glove side must be left or right, got {side!r}")
    return SIDE_SENSORS[side]


def encode_sample(side: str, raw: np.ndarray, quat_wxyz: np.ndarray) -> bytes:
    """Packet 01 then packet 02 of one sample (134 + 150 bytes).

    raw: (256,) uint8; quat_wxyz: (4,) float, sent as little-endian float32 w, x, y, z.
    """
    raw = np.asarray(raw)
    if raw.shape != (RAW_SLOTS,) or raw.dtype != np.uint8:
        raise ValueError(f"raw must be (256,) uint8, got {raw.shape} {raw.dtype}")
    quat = np.asarray(quat_wxyz, dtype="<f4")
    if quat.shape != (4,):
        raise ValueError(f"quat_wxyz must have 4 values, got shape {quat.shape}")
    sensor = sensor_type(side)
    return b"".join((SYNC, bytes((FIRST_HALF, sensor)), raw[:HALF_SLOTS].tobytes(),
                     SYNC, bytes((SECOND_HALF, sensor)), raw[HALF_SLOTS:].tobytes(), quat.tobytes()))


class JQStreamParser:
    """Turns JQ serial bytes, chunked in any way, into samples of both hands.

    Not thread-safe: one reader feeds it. After `feed` returns at most `MAX_BUFFERED` bytes stay buffered.
    """

    def __init__(self) -> None:
        self.counters = JQParserCounters()
        self._buffer = bytearray()
        self._locked = False
        self._skipped = False
        self._first_halves: dict[int, bytes] = {}

    @property
    def buffered(self) -> int:
        """Bytes kept for the next feed (an incomplete or unconfirmed packet, or a partial sync)."""
        return len(self._buffer)

    def reset(self) -> None:
        """Start over as on a new stream (after a reconnect); counters carry on."""
        self.counters.discarded_bytes += len(self._buffer)
        self._buffer.clear()
        self._forget_first_halves()
        self._locked = self._skipped = False

    def feed(self, data: bytes | bytearray | memoryview) -> list[JQSample]:
        """Parse the next bytes of the stream; returns the samples completed by them, oldest first."""
        self.counters.bytes_in += len(data)
        buf = self._buffer
        buf += data
        size, pos, samples = len(buf), 0, []
        while True:
            if not self._locked:
                found = buf.find(SYNC, pos)
                if found < 0:
                    pos = self._skip(pos, max(pos, size - len(SYNC) + 1))
                    break
                pos = self._skip(pos, found)
            if size < pos + HEADER_BYTES:
                break
            length = PACKET_BYTES.get(buf[pos + 4])
            if length is not None and size < pos + length + len(SYNC):
                break
            if length is None or not buf.startswith(SYNC, pos + length):
                self._lose_lock()
                pos = self._skip(pos, pos + 1)
                continue
            if self._locked or not self._skipped:
                self._take(buf, pos, length, samples)
            else:
                self.counters.packets += 1
                self.counters.dropped_packets += 1
            self._locked = True
            pos += length
        del buf[:pos]
        self.counters.samples += len(samples)
        return samples

    def _skip(self, start: int, end: int) -> int:
        if end > start:
            self.counters.discarded_bytes += end - start
            self._skipped = True
        return end

    def _lose_lock(self) -> None:
        if self._locked:
            self._locked = False
            self.counters.resyncs += 1
            self._forget_first_halves()

    def _forget_first_halves(self) -> None:
        self.counters.dropped_packets += len(self._first_halves)
        self._first_halves.clear()

    def _take(self, buf: bytearray, pos: int, length: int, samples: list[JQSample]) -> None:
        """Use the confirmed packet buf[pos:pos + length]."""
        counters = self.counters
        counters.packets += 1
        sensor = buf[pos + 5]
        side = SENSOR_SIDES.get(sensor)
        if side is None:
            counters.other_sensor_packets += 1
            return
        half = bytes(buf[pos + HEADER_BYTES:pos + HEADER_BYTES + HALF_SLOTS])
        if length == PACKET_BYTES[FIRST_HALF]:
            if sensor in self._first_halves:
                counters.dropped_packets += 1
            self._first_halves[sensor] = half
            return
        first = self._first_halves.pop(sensor, None)
        if first is None:
            counters.dropped_packets += 1
            return
        quat_wxyz = np.frombuffer(bytes(buf[pos + HEADER_BYTES + HALF_SLOTS:pos + length]), "<f4")
        if not np.isfinite(quat_wxyz).all():
            counters.invalid_quaternions += 1
            quat_wxyz = INVALID_QUATERNION
        samples.append(JQSample(side, np.frombuffer(first + half, np.uint8), quat_wxyz))
