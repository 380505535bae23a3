"""Benchmark: JQ glove parser throughput on a realistic two-glove stream, as a multiple of the line rate.

    .venv/bin/python benchmarks/glove_parser.py [--seconds 120] [--seed 0]

The stream carries two gloves (left and right) at 100 samples/s each, their packets interleaved at
random (each glove's 01 before its 02), with mostly idle pressure bytes and a few presses, and is fed
to one parser in chunks of 64–4096 bytes, as reads from a serial port return them. Two gloves at the
line rate are 2 × 100 Hz × (134 + 150) bytes = 56.8 KB/s.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from touchanything.devices.hardware.jq_protocol import FIRST_HALF, PACKET_BYTES, JQStreamParser, encode_sample

SAMPLE_RATE_HZ = 100
SAMPLE_BYTES = sum(PACKET_BYTES.values())
LINE_RATE_BYTES_PER_S = 2 * SAMPLE_RATE_HZ * SAMPLE_BYTES


def glove_sample(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Idle noise (0–5) with, now and then, a press of 20–60 slots up to full scale; a unit quaternion."""
    raw = rng.integers(0, 6, 256, dtype=np.uint8)
    if rng.random() < 0.3:
        slots = rng.choice(256, size=int(rng.integers(20, 60)), replace=False)
        raw[slots] = rng.integers(40, 256, slots.size, dtype=np.uint8)
    quat = rng.normal(size=4).astype(np.float32)
    return raw, quat / np.linalg.norm(quat)


def two_glove_stream(seconds: float, seed: int = 0) -> tuple[bytes, int]:
    """The byte stream of both gloves for `seconds`, and the number of samples it holds."""
    rng = np.random.default_rng(seed)
    split = PACKET_BYTES[FIRST_HALF]
    packets = []
    ticks = int(seconds * SAMPLE_RATE_HZ)
    for _ in range(ticks):
        left, right = (encode_sample(side, *glove_sample(rng)) for side in ("left", "right"))
        queues = [[left[:split], left[split:]], [right[:split], right[split:]]]
        while queues:
            queue = queues[int(rng.integers(len(queues)))]
            packets.append(queue.pop(0))
            queues = [q for q in queues if q]
    return b"".join(packets), 2 * ticks


def chunked(stream: bytes, seed: int = 0, smallest: int = 64, largest: int = 4096) -> list[bytes]:
    """The stream cut into reads of random sizes in [smallest, largest]."""
    rng = np.random.default_rng(seed)
    cuts = np.cumsum(rng.integers(smallest, largest + 1, size=len(stream) // smallest + 1))
    cuts = cuts[cuts < len(stream)]
    return [stream[a:b] for a, b in zip([0, *cuts], [*cuts, len(stream)])]


def measure(seconds: float = 120.0, seed: int = 0) -> dict:
    """Parse a `seconds`-long stream; throughput in MB/s and as a multiple of the two-glove line rate."""
    stream, samples = two_glove_stream(seconds, seed)
    chunks = chunked(stream, seed)
    parser = JQStreamParser()
    started = time.perf_counter()
    parsed = sum(len(parser.feed(chunk)) for chunk in chunks)
    elapsed = time.perf_counter() - started
    # The newest packet waits for its successor's sync, so the last sample stays pending.
    if parsed != samples - 1 or parser.counters.resyncs:
        raise RuntimeError(f"parsed {parsed} of {samples} samples: {parser.counters}")
    return {
        "stream_mb": len(stream) / 1e6, "chunks": len(chunks), "samples": parsed, "seconds": elapsed,
        "mb_per_s": len(stream) / elapsed / 1e6, "samples_per_s": parsed / elapsed,
        "x_line_rate": len(stream) / elapsed / LINE_RATE_BYTES_PER_S,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120.0, help="length of the simulated stream")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    figures = measure(args.seconds, args.seed)
    print(f"stream        {figures['stream_mb']:.1f} MB in {figures['chunks']} reads, {figures['samples']} samples")
    print(f"parse time    {figures['seconds']:.2f} s")
    print(f"throughput    {figures['mb_per_s']:.1f} MB/s, {figures['samples_per_s']:.0f} samples/s")
    print(f"line rate     {figures['x_line_rate']:.0f}× the two-glove line rate "
          f"({LINE_RATE_BYTES_PER_S / 1000:.1f} KB/s)")


if __name__ == "__main__":
    main()
