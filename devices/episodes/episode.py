"""The Episode record: one recorded trajectory, aligned to a common frame count, from any format."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from touchanything.core.snapshot import FPS, FRAME_PERIOD_US, VIEW_NAMES
from touchanything.devices.episodes.episode_files import PressureFile
from touchanything.devices.episodes.episode_streams import GloveStream, HandStream, TrackerStream


class FrameSource(Protocol):
    """Random access to one camera's frames as (H, W, 3) uint8 RGB."""

    width: int
    height: int
    num_frames: int

    def read(self, index: int) -> np.ndarray | None: ...

    def close(self) -> None: ...


@dataclass
class Episode:
    """Every stream of a trajectory cut or padded to `num_frames` (problems say which and why).

    views: {view name: FrameSource} for the readable cameras (official names ego, wrist_left, wrist_right).
    timestamps_us: (T,) int64. Streams that are absent or unreadable are None.
    """

    path: Path
    scene: str
    task: str
    trajectory_id: str
    num_frames: int
    views: dict[str, FrameSource]
    timestamps_us: np.ndarray
    wilor: HandStream | None = None
    rokoko: HandStream | None = None
    trackers: TrackerStream | None = None
    pressure: PressureFile | None = None
    glove: GloveStream | None = None
    problems: list[str] = field(default_factory=list)
    fps: float = FPS

    @property
    def view_names(self) -> tuple[str, ...]:
        """Available views in the official order."""
        return tuple(v for v in VIEW_NAMES if v in self.views)

    def hands(self, source: str) -> HandStream | None:
        """The pose stream named `wilor` or `rokoko`."""
        if source not in ("wilor", "rokoko"):
            raise ValueError(f"unknown pose source {source!r} (expected wilor or rokoko)")
        return self.wilor if source == "wilor" else self.rokoko

    def close(self) -> None:
        for source in self.views.values():
            source.close()

    def __enter__(self) -> Episode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def synthetic_timestamps(frames: int) -> np.ndarray:
    """The official timestamps t_i = i · 33333 µs."""
    return np.arange(frames, dtype=np.int64) * FRAME_PERIOD_US


def align_note(lengths: dict[str, int], frames: int) -> str | None:
    """A problem line when the streams' frame counts differ, else None."""
    if len(set(lengths.values())) <= 1:
        return None
    listed = ", ".join(f"{name} {n}" for name, n in lengths.items())
    return f"frame counts differ ({listed}); aligned to {frames} frames"


SHOWN_PER_STREAM = 3
"""Problems of one stream quoted in an episode's damage line (the others are counted)."""


def problems_in_brief(problems: list[str], where: Path) -> list[str]:
    """An episode's problem lines as one part per stream they name, without the episode's path `where`:
    "wilor_hands.json: line 5: invalid JSON …", or "wilor_hands.json (3 problems): line 5: … / line 9: … / 1 more"."""
    streams: dict[str, list[str]] = {}
    for problem in problems:
        text = problem[len(str(where)):].lstrip("/: ") if problem.startswith((f"{where}/", f"{where}: ")) else problem
        stream, _, what = text.partition(": ")
        streams.setdefault(stream, []).append(what)
    parts = []
    for stream, whats in streams.items():
        more = len(whats) - SHOWN_PER_STREAM
        quoted = " / ".join([w for w in whats[:SHOWN_PER_STREAM] if w] + ([f"{more} more"] if more > 0 else []))
        name = stream if len(whats) == 1 else f"{stream} ({len(whats)} problems)"
        parts.append(f"{name}: {quoted}" if quoted else name)
    return parts
