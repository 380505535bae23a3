"""JQ pressure glove: the protocol parser (hypothesis properties), the serial adapter through real ptys
from the simulated glove, and the parser's throughput."""
from __future__ import annotations

import os
import runpy
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from touchanything.core.errors import UserError
from touchanything.core.snapshot import HANDS
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.hardware.jq_glove import JQGlove, JQGloveConfig
from touchanything.devices.hardware.jq_protocol import MAX_BUFFERED, SYNC, JQStreamParser, encode_sample
from touchanything.devices.sim.glove_serial import SimulatedGloveSerial, episode_glove_provider

ROOT = Path(__file__).resolve().parents[2]
FIRST, SAMPLE = 134, 284
quaternions = st.lists(st.floats(-2, 2, width=32), min_size=4, max_size=4)


def indexed_sample(index: int) -> tuple[np.ndarray, np.ndarray]:
    """Random pressure bytes carrying the sample index (uint16) at the start of both halves."""
    raw = np.random.default_rng(index).integers(0, 256, 256, dtype=np.uint8)
    raw[0:2] = raw[128:130] = np.frombuffer((index % 65536).to_bytes(2, "little"), np.uint8)
    quat = np.array([np.cos(index / 50), np.sin(index / 50), 0.5, -0.25], np.float32)
    return raw, quat


def sample_index(raw: np.ndarray) -> int:
    return int.from_bytes(raw[0:2].tobytes(), "little")


def feed_all(parser: JQStreamParser, data: bytes, cuts: list[int]) -> list:
    """Feed `data` cut at `cuts`, checking the buffer bound after every feed."""
    samples = []
    for start, end in zip([0, *cuts], [*cuts, len(data)]):
        samples += parser.feed(data[start:end])
        assert parser.buffered <= MAX_BUFFERED
    return samples


def same(sample, side: str, raw: np.ndarray, quat: np.ndarray) -> bool:
    return sample.side == side and np.array_equal(sample.raw, raw) and np.array_equal(sample.quat_wxyz, quat)


# --- encoding and parsing -------------------------------------------------------------------------


def test_encode_sample_layout() -> None:
    raw = np.arange(256, dtype=np.uint8)
    data = encode_sample("right", raw, np.array([1, 0, 0, 0], np.float32))
    assert len(data) == SAMPLE and data[:6] == SYNC + b"\x01\x02" and data[FIRST:FIRST + 6] == SYNC + b"\x02\x02"
    assert data[6:FIRST] == bytes(range(128)) and data[FIRST + 6:FIRST + 134] == bytes(range(128, 256))
    assert np.array_equal(np.frombuffer(data[-16:], "<f4"), [1, 0, 0, 0])
    with pytest.raises(ValueError, match="left or right"):
        encode_sample("foot", raw, np.zeros(4))
    with pytest.raises(ValueError, match="uint8"):
        encode_sample("left", raw.astype(np.int32), np.zeros(4))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(HANDS), st.binary(min_size=256, max_size=256), quaternions),
                min_size=1, max_size=6),
       st.lists(st.integers(0, 6 * SAMPLE + 4), max_size=30))
def test_any_chunking_gives_exactly_the_encoded_samples(encoded, cuts) -> None:
    data = b"".join(encode_sample(side, np.frombuffer(raw, np.uint8), q) for side, raw, q in encoded) + SYNC
    parser = JQStreamParser()
    samples = feed_all(parser, data, sorted({c for c in cuts if 0 < c < len(data)}))
    assert len(samples) == len(encoded)
    for sample, (side, raw, quat) in zip(samples, encoded):
        assert same(sample, side, np.frombuffer(raw, np.uint8), np.array(quat, np.float32))
    counters = parser.counters
    assert (counters.samples, counters.packets, counters.bytes_in) == (len(encoded), 2 * len(encoded), len(data))
    assert counters.resyncs == counters.dropped_packets == counters.discarded_bytes == 0


def corrupt(data: bytes, edits: list[tuple[int, str, int, bytes]]) -> tuple[bytes, int, int]:
    """Apply (packet start, kind, offset, garbage) edits, one per packet: "insert" garbage, "delete"
    1–133 bytes within the packet, "flip" a sync or order byte. Returns the stream and the first and
    last edited byte (original positions)."""
    out, first, last = bytearray(data), len(data), 0
    for start, kind, offset, garbage in sorted(edits, reverse=True):
        at = start + offset
        if kind == "insert":
            out[at:at] = garbage
            span = 0
        elif kind == "delete":
            span = min(1 + len(garbage) % 133, start + FIRST - at)
            del out[at:at + span]
        else:
            at, span = start + offset % 5, 1
            out[at] ^= garbage[0] if garbage[0] else 0xFF
        first, last = min(first, at), max(last, at + span)
    return bytes(out), first, last


@settings(max_examples=150, deadline=None)
@given(st.integers(3, 12), st.data())
def test_corruption_never_yields_a_foreign_sample_and_the_parser_recovers(count, data) -> None:
    sides = data.draw(st.lists(st.sampled_from(HANDS), min_size=count, max_size=count))
    stream = b"".join(encode_sample(sides[i], *indexed_sample(i)) for i in range(count)) + SYNC
    starts = [SAMPLE * (i // 2) + FIRST * (i % 2) for i in range(2 * count)]
    edited = data.draw(st.lists(st.integers(0, 2 * count - 1), min_size=1, max_size=4, unique=True))
    kinds = {p: data.draw(st.sampled_from(["insert", "delete", "flip"])) for p in edited}
    offsets = {p: data.draw(st.integers(0, 130)) for p in edited}
    # Bytes deleted from a payload and garbage inserted right before the next packet's sync can restore
    # the packet's length exactly: a payload substitution, which no parser can detect (no checksum).
    assume(not any(kinds[p] == "delete" and kinds.get(p + 1) == "insert" and offsets[p + 1] == 0 for p in edited))
    edits = [(starts[p], kinds[p], offsets[p], data.draw(st.binary(min_size=1, max_size=200))) for p in edited]
    broken, first, last = corrupt(stream, edits)
    parser = JQStreamParser()
    samples = feed_all(parser, broken, sorted(set(data.draw(st.lists(st.integers(1, len(broken) - 1), max_size=20)))))
    indices = [sample_index(s.raw) for s in samples]
    assert indices == sorted(set(indices)), "samples repeated or out of order"
    for sample, index in zip(samples, indices):
        assert same(sample, sides[index], *indexed_sample(index)), f"sample {index} is not the one encoded"
    intact_before = [i for i in range(count) if SAMPLE * (i + 1) + len(SYNC) <= first]
    recovered_after = [i for i in range(count) if SAMPLE * i >= last + 2 * FIRST]
    assert set(intact_before + recovered_after) <= set(indices)
    assert parser.counters.resyncs >= 1 or not (intact_before and recovered_after)


def plant_false_sync(raw: np.ndarray, half: int, offset: int, order: int, sensor: int) -> None:
    """Write `AA 55 03 99 order sensor` into one half of the pressure bytes."""
    at = 128 * half + offset
    raw[at:at + 6] = np.frombuffer(SYNC + bytes((order, sensor)), np.uint8)


@settings(max_examples=150, deadline=None)
@given(st.integers(4, 10), st.data())
def test_false_syncs_in_payloads_never_make_a_sample(count, data) -> None:
    """Pressure bytes that read like a packet start, at any place, with the stream joined mid-packet."""
    samples_in = []
    for i in range(count):
        raw, quat = indexed_sample(i)
        for half in (0, 1):
            if data.draw(st.booleans()):
                plant_false_sync(raw, half, data.draw(st.integers(2, 122)), data.draw(st.sampled_from([1, 2])),
                                 data.draw(st.sampled_from([1, 2])))
        samples_in.append((raw, quat))
    stream = b"".join(encode_sample("left", raw, quat) for raw, quat in samples_in) + SYNC
    join = data.draw(st.integers(0, SAMPLE))
    parser = JQStreamParser()
    samples = feed_all(parser, stream[join:], sorted(set(data.draw(st.lists(st.integers(1, 500), max_size=10)))))
    indices = [sample_index(s.raw) for s in samples]
    assert indices == sorted(set(indices))
    for sample, index in zip(samples, indices):
        assert same(sample, "left", *samples_in[index])
    assert set(range(count)) - set(indices) <= set(range((join + 2 * SAMPLE) // SAMPLE))
    if join == 0:
        assert indices == list(range(count))


def test_false_sync_confirmed_by_a_real_one_after_a_glitch_is_not_used() -> None:
    """A planted `AA 55 03 99 01 01` becomes a confirmed packet once a glitch inserts exactly as many
    bytes as it sits into its packet: it may only re-establish the lock."""
    raws = [indexed_sample(i) for i in range(4)]
    plant_false_sync(raws[1][0], 0, 40, 1, 1)
    packets = [encode_sample("left", raw, quat) for raw, quat in raws]
    stream = packets[0] + packets[1][:FIRST] + b"\x00" * (6 + 40) + packets[1][FIRST:] + packets[2] + packets[3] + SYNC
    parser = JQStreamParser()
    assert [sample_index(s.raw) for s in parser.feed(stream)] == [0, 2, 3]
    assert parser.counters.resyncs == 1


def test_unmatched_halves_are_dropped_and_counted() -> None:
    a, b, c = (encode_sample(side, *indexed_sample(i)) for i, side in enumerate(("left", "right", "left")))
    parser = JQStreamParser()
    lone_second = b[FIRST:]
    interleaved = a[:FIRST] + b[:FIRST] + a[FIRST:] + b[FIRST:]
    stream = a + lone_second + c[:FIRST] + interleaved + c[FIRST:] + SYNC
    indices = [sample_index(s.raw) for s in parser.feed(stream)]
    # dropped: the lone right 02; c's 01, replaced by a's; c's 02, whose 01 is gone
    assert indices == [0, 0, 1]
    assert parser.counters.dropped_packets == 3 and parser.counters.resyncs == 0


def test_other_sensor_types_are_counted_and_ignored() -> None:
    left = encode_sample("left", *indexed_sample(0))
    foot = bytearray(encode_sample("left", *indexed_sample(1)))
    foot[5] = foot[FIRST + 5] = 0x03
    body = bytearray(encode_sample("left", *indexed_sample(2)))
    body[5] = body[FIRST + 5] = 0x7F
    parser = JQStreamParser()
    samples = parser.feed(left + bytes(foot) + bytes(body) + left + SYNC)
    assert [sample_index(s.raw) for s in samples] == [0, 0]
    assert parser.counters.other_sensor_packets == 4 and parser.counters.resyncs == 0


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_quaternion_keeps_the_pressure(bad: float) -> None:
    raw, _ = indexed_sample(7)
    parser = JQStreamParser()
    [sample] = parser.feed(encode_sample("right", raw, np.array([1, bad, 0, 0], np.float32)) + SYNC)
    assert np.array_equal(sample.raw, raw) and np.isnan(sample.quat_wxyz).all()
    assert sample.quat_wxyz.dtype == np.float32 and parser.counters.invalid_quaternions == 1


@settings(max_examples=100, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=600),
                          st.sampled_from([SYNC, SYNC + b"\x01", SYNC + b"\x02\x01", b"\xaa"])), max_size=80))
def test_garbage_keeps_the_buffer_bounded(pieces) -> None:
    parser = JQStreamParser()
    for piece in pieces:
        parser.feed(piece)
        assert parser.buffered <= MAX_BUFFERED
    total = sum(map(len, pieces))
    assert parser.counters.bytes_in == total
    if not any(SYNC in piece for piece in pieces):
        assert parser.counters.discarded_bytes + parser.buffered == total


def test_reset_forgets_partial_packets_but_keeps_counters() -> None:
    data = encode_sample("left", *indexed_sample(0))
    parser = JQStreamParser()
    parser.feed(data[:FIRST] + SYNC)
    parser.reset()
    assert parser.buffered == 0 and parser.counters.dropped_packets == 1
    assert parser.counters.discarded_bytes == len(SYNC)
    assert [sample_index(s.raw) for s in parser.feed(data + SYNC)] == [0]
    assert parser.counters.bytes_in == FIRST + len(data) + 2 * len(SYNC)


# --- the adapter through real ptys ----------------------------------------------------------------


def wait_for(condition, what: str, timeout_s: float = 15.0):
    """Poll `condition` until it returns something truthy; fail after `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if value := condition():
            return value
        time.sleep(0.005)
    raise AssertionError(f"timed out waiting for {what}")


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


def check_reading(reading, side: str) -> None:
    raw, quat = indexed_sample(sample_index(reading.raw))
    assert reading.side == side and np.array_equal(reading.raw, raw) and np.array_equal(reading.quat_wxyz, quat)


def collect(glove: JQGlove, readings: list, until, what: str) -> None:
    """Append the new readings seen while polling `latest()` until `until()` holds."""

    def newest():
        reading = glove.latest()
        if reading is not None and (not readings or reading is not readings[-1]):
            readings.append(reading)
        return until()

    wait_for(newest, what)


def test_glove_streams_samples_through_a_pty(tmp_path: Path) -> None:
    fds, threads = open_fds(), threading.active_count()
    with SimulatedGloveSerial("left", indexed_sample, tmp_path) as sim:
        glove = JQGlove(JQGloveConfig(str(sim.path), "left"))
        assert glove.status() == "disconnected" and not glove.is_connected
        with glove:
            assert glove.is_connected
            readings = []
            collect(glove, readings, lambda: glove.counters.samples >= 150, "150 samples")
            sim.inject(b"\x00\xaa\x55" * 100)
            resynced = glove.counters.samples
            collect(glove, readings, lambda: glove.counters.parser.resyncs >= 1
                                and glove.counters.samples >= resynced + 20, "a resync and 20 more samples")
            status = glove.status()
        assert glove.status() == "disconnected"
    for reading in readings:
        check_reading(reading, "left")
    stamps, indices = [r.t_us for r in readings], [sample_index(r.raw) for r in readings]
    assert stamps == sorted(stamps) and indices == sorted(set(indices))
    assert status.startswith(f"connected {sim.path} → /dev/pts/") and " Hz, age " in status
    assert status.endswith(" resyncs, 0 reconnects")
    rate = float(status.split(", ")[1].split()[0])
    assert 50 <= rate <= 150, status
    assert open_fds() == fds and threading.active_count() == threads


def test_glove_on_the_other_port_is_reported(tmp_path: Path) -> None:
    with SimulatedGloveSerial("right", indexed_sample, tmp_path) as sim, \
            JQGlove(JQGloveConfig(str(sim.path), "left")) as glove:
        status = wait_for(lambda: "swap" in (s := glove.status()) and s, "the swap-ports message")
        assert status == f"port {sim.path} carries the right glove; swap ports in the scene file"
        assert glove.latest() is None and glove.counters.other_side_samples > 0 and glove.counters.samples == 0


def test_unplugged_glove_reconnects_on_its_new_device(tmp_path: Path) -> None:
    with SimulatedGloveSerial("right", indexed_sample, tmp_path) as sim, \
            JQGlove(JQGloveConfig(str(sim.path), "right", reconnect_backoff_s=(0.05, 0.2))) as glove:
        wait_for(glove.latest, "a first sample")
        old_device = os.path.realpath(sim.path)
        holder = os.open(old_device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            sim.unplug()
            unplugged_us = time.monotonic_ns() // 1000
            status = wait_for(lambda: (s := glove.status()).startswith("disconnected") and s, "disconnected")
            assert str(sim.path) in status and glove.counters.reconnects == 0
            time.sleep(0.3)
            sim.replug()
            new_device = os.path.realpath(sim.path)
            assert new_device != old_device
            fresh = wait_for(lambda: (r := glove.latest()) and r.t_us > unplugged_us and r, "a sample after replug")
        finally:
            os.close(holder)
        check_reading(fresh, "right")
        assert glove.counters.reconnects == 1
        assert glove.status().startswith(f"connected {sim.path} → {new_device},")


def test_absent_or_unusable_port_is_a_user_error(tmp_path: Path) -> None:
    fds, threads = open_fds(), threading.active_count()
    missing = tmp_path / "usb-Juqiao-glove-if00"
    with pytest.raises(UserError, match=rf"^glove port {missing} does not exist; .*/dev/serial/by-id"):
        JQGlove(JQGloveConfig(str(missing), "left")).connect()
    missing.symlink_to(tmp_path / "ttyACM9")
    with pytest.raises(UserError, match="does not exist"):
        JQGlove(JQGloveConfig(str(missing), "left")).connect()
    not_a_tty = tmp_path / "notes.txt"
    not_a_tty.write_text("x")
    glove = JQGlove(JQGloveConfig(str(not_a_tty), "left"))
    with pytest.raises(UserError, match=rf"^cannot open glove port {not_a_tty}: "):
        glove.connect()
    assert not glove.is_connected and open_fds() == fds and threading.active_count() == threads
    with pytest.raises(UserError, match="left or right"):
        JQGloveConfig("/dev/ttyACM0", "both")
    with pytest.raises(UserError, match="back-off"):
        JQGloveConfig("/dev/ttyACM0", "left", reconnect_backoff_s=(1.0, 0.5))


def test_episode_glove_stream_as_a_100_hz_provider(episode_dir: Path) -> None:
    with open_episode(episode_dir) as episode:
        provider = episode_glove_provider(episode, "right")
        frames = episode.num_frames
        for index in (0, 1, 3, 4, 10, 99, 100, 1000, 10 * frames // 3 + 1):
            raw, quat = provider(index)
            frame = (index * 30 // 100) % frames
            assert np.array_equal(raw, episode.glove.raw[frame, 1])
            assert np.array_equal(quat, episode.glove.quat_wxyz[frame, 1]) and quat.dtype == np.float32


# --- throughput -----------------------------------------------------------------------------------


def test_parser_keeps_up_with_two_gloves_many_times_over() -> None:
    bench = runpy.run_path(str(ROOT / "benchmarks" / "glove_parser.py"))
    figures = bench["measure"](seconds=20)
    assert figures["x_line_rate"] >= 20, figures
