"""Rows of a Rerun recording held back and sent as columns: one `send_columns` call per entity (and part of it)
for every `BATCH_ROWS` rows instead of one `log` call per row. A call costs about 0.15 ms in the SDK whatever it
carries; at some twenty entities per frame that was half of what logging a frame cost."""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import rerun as rr

BATCH_ROWS = 60
"""Rows kept per entity before they are sent: two seconds of frames at 30 fps. Each send is one chunk, and
the file keeps an entry per chunk in memory for its footer until it closes (about 1.5 MB a minute with 15)."""


class Columns(Protocol):
    """What rows are made of: an archetype (`rr.Scalars`, …) or anything with its `columns(**components)`."""

    def columns(self, **components: np.ndarray | list) -> rr.ComponentColumnList: ...


@dataclass
class _Rows:
    archetype: Columns
    frames: list[int] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    lengths: dict[str, list[int]] = field(default_factory=lambda: defaultdict(list))
    components: dict[str, list] = field(default_factory=lambda: defaultdict(list))


def _joined(values: list) -> np.ndarray | list:
    """The rows of one component as one batch: arrays concatenated, lists (of blobs) chained."""
    if isinstance(values[0], np.ndarray):
        return np.concatenate(values)
    return [item for row in values for item in row]


class ColumnBuffer:
    """`put` rows per entity (each component's instances of the row: an array (n, ...) or a list of n items; n may
    differ between components); they are sent when an entity holds BATCH_ROWS rows, and all of them on `flush`.
    Rows of one entity that carry different components (e.g. a mesh's geometry and each of its paints, logged at
    different moments) go under different `part`s: every row of a part has all of its components. `clear` logs a
    clear at once (the store orders rows by their time, not by arrival)."""

    def __init__(self, stream: rr.RecordingStream) -> None:
        self.stream = stream
        self._rows: dict[tuple[str, str], _Rows] = {}

    def put(self, entity: str, archetype: Columns, frame: int, time_s: float, part: str = "",
            **components: np.ndarray | list) -> None:
        key = (entity, part)
        rows = self._rows.get(key)
        if rows is None:
            rows = self._rows[key] = _Rows(archetype)
        rows.frames.append(int(frame))
        rows.times.append(float(time_s))
        for name, value in components.items():
            rows.components[name].append(value)
            rows.lengths[name].append(len(value))
        if len(rows.frames) >= BATCH_ROWS:
            self._send(key)

    def clear(self, entity: str, frame: int, time_s: float) -> None:
        self.stream.set_time("frame", sequence=int(frame))
        self.stream.set_time("capture_time", duration=float(time_s))
        self.stream.log(entity, rr.Clear(recursive=False))

    def _send(self, key: tuple[str, str]) -> None:
        rows = self._rows.pop(key)
        indexes = [rr.TimeColumn("frame", sequence=np.array(rows.frames, np.int64)),
                   rr.TimeColumn("capture_time", duration=np.array(rows.times, np.float64))]
        columns: list = []
        for name, values in rows.components.items():
            columns.extend(rows.archetype.columns(**{name: _joined(values)}).partition(rows.lengths[name]))
        self.stream.send_columns(key[0], indexes=indexes, columns=columns)

    def flush(self) -> None:
        """Send every row held back."""
        for key in list(self._rows):
            self._send(key)
