"""What a served recording's data server still holds for a viewer, counted where the rows are sent.

Rerun's gRPC server (rerun-sdk 0.41, `re_grpc_server`) keeps every message it receives so that a viewer connecting
later gets the whole recording, within its memory limit (the stream to viewers already connected is bounded on its
own and applies back-pressure: it drops nothing). Over the limit it drops its oldest
temporal messages — in silence, for every viewer that connects afterwards. It counts a message LZ4-compressed;
`ServedHistory` counts each of its Arrow buffers LZ4-compressed on its own plus an overhead per message or row, an
estimate from above, and replays the server's rule on those sizes: "0 dropped" holds, and a count above 0 is at
least what the server dropped ("up to")."""
from __future__ import annotations

from collections import Counter, deque
from collections.abc import Iterable, Sequence
from typing import Any

import pyarrow as pa
import rerun as rr

SERVER_MEMORY_LIMIT = 512 << 20
"""The data server's memory limit in bytes (`rr.GrpcServerSink(server_memory_limit=…)`)."""
MESSAGE_OVERHEAD, ROW_OVERHEAD = 4096, 128
"""Bytes beyond the values: per message sent as columns (its Arrow schema, the transport's headers), and per row
logged on its own (its row id and times; the SDK batches such rows into a message per entity and half second)."""
KINDS = (("world/surface", "hand surfaces"), ("world/hands", "skeletons"), ("cameras/ego/hands", "skeletons"),
         ("cameras", "cameras"), ("pressure", "maps"), ("trackers", "trackers"), ("contact", "series"),
         ("metrics", "series"), ("engine", "series"))
"""Entity path prefixes and the kind of rows a summary names them by (the first match counts)."""


def entity_kind(entity: str) -> str:
    """The kind of rows `entity` holds ("hand surfaces", "cameras", …; else its first path segment)."""
    path = entity.strip("/")
    return next((kind for prefix, kind in KINDS if path == prefix or path.startswith(prefix + "/")), path.split("/")[0])


def _compressed_bytes(arrays: Iterable[pa.Array]) -> int:
    """The arrays' buffers, each LZ4-compressed on its own (as the transport, which compresses them together)."""
    codec = pa.Codec("lz4_raw")
    return sum(codec.compress(buffer).size for array in arrays for buffer in array.buffers() if buffer is not None)


class ServedHistory:
    """`sent(…)` each message as it goes to a data server of `memory_limit` bytes; `rows` {entity: temporal rows
    sent}, `dropped` {kind: rows the server may have dropped to keep what it holds within the limit (oldest
    temporal messages first; static ones count, and are dropped only when no temporal one is left, which
    is not counted)}."""

    def __init__(self, memory_limit: int = SERVER_MEMORY_LIMIT) -> None:
        self.memory_limit = memory_limit
        self.rows: Counter[str] = Counter()
        self.dropped: Counter[str] = Counter()
        self._held: deque[tuple[str, int, int]] = deque()
        self._bytes = 0

    def sent(self, entity: str, rows: int, size: int, static: bool) -> None:
        """`rows` rows of `entity` sent, `size` bytes with their overhead (static: kept by the server to the end)."""
        while self._held and self._bytes + size > self.memory_limit:
            kind, dropped_rows, dropped_size = self._held.popleft()
            self.dropped[kind] += dropped_rows
            self._bytes -= dropped_size
        self._bytes += size
        if not static:
            self.rows[entity.strip("/")] += rows
            self._held.append((entity_kind(entity), rows, size))

    def line(self) -> str:
        """"rerun     served: 7783 rows held for any viewer, 0 dropped", or what may be gone and why."""
        total = sum(self.rows.values())
        if not self.dropped:
            return f"rerun     served: {total} rows held for any viewer, 0 dropped"
        kinds = ", ".join(f"{kind} {rows}" for kind, rows in self.dropped.most_common())
        return (f"rerun     served: {total} rows; up to {sum(self.dropped.values())} of the oldest dropped by the data server's "
                f"memory limit ({self.memory_limit / 2**20:g} MiB; a viewer connecting now misses them): {kinds}")


class CountingStream:
    """The calls of a `rr.RecordingStream` that log rows (`log`, `send_columns`, `set_time`), passed on to it and
    counted in `history`."""

    def __init__(self, stream: rr.RecordingStream, history: ServedHistory) -> None:
        self.stream = stream
        self.history = history

    def set_time(self, timeline: str, **time: Any) -> None:
        self.stream.set_time(timeline, **time)

    def log(self, entity: str, entity_data: rr.AsComponents, static: bool = False) -> None:
        self.stream.log(entity, entity_data, static=static)
        size = _compressed_bytes(batch.as_arrow_array() for batch in entity_data.as_component_batches())
        self.history.sent(entity, 1, size + ROW_OVERHEAD, static)

    def send_columns(self, entity: str, indexes: Sequence[rr.TimeColumn], columns: Iterable[rr.ComponentColumn]) -> None:
        columns = list(columns)
        self.stream.send_columns(entity, indexes=indexes, columns=columns)
        rows = len(indexes[0].as_arrow_array()) if indexes else 1
        size = _compressed_bytes(column.as_arrow_array() for column in [*indexes, *columns])
        self.history.sent(entity, rows, size + MESSAGE_OVERHEAD, False)
