"""Reading a .rrd file back with the Rerun SDK's own reader (`rerun.chunk.RrdReader`): per entity, the rows on
the `frame` timeline and their component values, in the viewer's order (by frame, then by row id: of two rows
at one frame the later logged is the one shown)."""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from rerun.chunk import RrdReader


@dataclass
class EntityRows:
    """The temporal rows of one entity: `frames[i]` and `values[component][i]` (None where the row has no such
    component, e.g. a clear)."""

    frames: list[int] = field(default_factory=list)
    row_ids: list[bytes] = field(default_factory=list)
    values: dict[str, list] = field(default_factory=lambda: defaultdict(list))

    def data_frames(self, component: str) -> list[int]:
        """The frames whose row holds `component` with at least one value (clears excluded)."""
        return [f for f, v in zip(self.frames, self.values[component]) if v]

    def at(self, component: str, frame: int):
        """The value of `component` in the last row at `frame` that holds it."""
        found = [v for f, v in zip(self.frames, self.values[component]) if f == frame and v]
        assert found, f"no {component} at frame {frame}"
        return found[-1]


def recording_rows(path: Path, store=None) -> tuple[dict[str, EntityRows], dict[str, list]]:
    """({entity: its temporal rows sorted by frame}, {entity: static component names}) of a recording in
    `path` (the first one, or `store` from `RrdReader(path).recordings()`)."""
    rows: dict[str, EntityRows] = defaultdict(EntityRows)
    static: dict[str, list] = defaultdict(list)
    for chunk in RrdReader(path).stream(store=store):
        batch = chunk.to_record_batch()
        names = [n for n in batch.schema.names if ":" in n and not n.startswith("rerun.")]
        if chunk.is_static:
            static[chunk.entity_path] += names
            continue
        if "frame" not in batch.schema.names:
            continue
        entity = rows[chunk.entity_path]
        frames = batch.column("frame").to_pylist()
        start = len(entity.frames)
        entity.frames += frames
        entity.row_ids += batch.column("rerun.controls.RowId").to_pylist()
        for name in set(names) | set(entity.values):
            column = batch.column(name).to_pylist() if name in names else [None] * len(frames)
            entity.values[name] += [None] * (start - len(entity.values[name])) + column
    for entity in rows.values():
        order = sorted(range(len(entity.frames)), key=lambda i: (entity.frames[i], entity.row_ids[i]))
        entity.frames = [entity.frames[i] for i in order]
        entity.row_ids = [entity.row_ids[i] for i in order]
        for name, values in entity.values.items():
            values += [None] * (len(order) - len(values))
            entity.values[name] = [values[i] for i in order]
    return dict(rows), dict(static)
