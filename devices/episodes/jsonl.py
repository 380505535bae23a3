"""JSON-lines files: one object per line, the line number is the frame index (blank lines count).

A broken line never shifts later frames: it becomes an empty row and a problem naming its line number.
Lines that were merged (a lost newline) or split (a stray newline), or lost outright, would shift every
later line; each row's own `frame_index` (the 0-based frame number, equal to the line number in an intact
file) puts it back in place. A row's index is trusted only when the next row's index agrees with it, so one
corrupted number moves nothing. Every such disagreement is a problem line.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

from touchanything.core.errors import DataError, describe

MAX_GAP = 1_000_000
"""A `frame_index` further ahead of the line order than this (about 9 hours at 30 fps) is not followed."""
TAIL_GAP = 30
"""The last line's index is followed when it skips at most this many frames (1 s) past the line order."""


def _frame_index(row: dict | None) -> int | None:
    value = row.get("frame_index") if row is not None else None
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def _parse(path: Path) -> tuple[list[dict | None], list[int], list[str]]:
    """One row per line (None for blank or broken lines), the numbers of the broken lines (not a JSON object) and
    the problems found, one line each."""
    rows: list[dict | None] = []
    broken: list[int] = []
    problems: list[str] = []
    try:
        handle = open(path, "rb")
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except OSError as exc:
        raise DataError(path, None, f"cannot open ({exc.strerror})") from None
    with handle:
        try:
            lines = list(handle)
        except OSError as exc:
            raise DataError(path, None, f"cannot read ({exc.strerror})") from None
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text:
            rows.append(None)
            continue
        try:
            obj = json.loads(text)
        except (UnicodeDecodeError, ValueError, RecursionError) as exc:
            reason = exc.msg if isinstance(exc, json.JSONDecodeError) else (
                "nested too deeply" if isinstance(exc, RecursionError) else "not UTF-8 text")
            problems.append(describe(path, f"line {number}", f"invalid JSON ({reason}); frame left empty"))
            broken.append(number)
            rows.append(None)
            continue
        if not isinstance(obj, dict):
            problems.append(describe(path, f"line {number}", "not a JSON object; frame left empty"))
            broken.append(number)
            obj = None
        rows.append(obj)
    return rows, broken, problems


def _trusted(indices: list[int | None], i: int) -> bool:
    """Line i's frame index is believed: the next line holding an index is as many frames after it as it is
    lines after it; for the last such line, its index follows the previous one's by at most `TAIL_GAP`
    frames more than the lines between them."""
    for j in range(i + 1, len(indices)):
        if indices[j] is not None:
            return indices[j] - indices[i] == j - i
    for j in range(i - 1, -1, -1):
        if indices[j] is not None:
            return indices[j] < indices[i] <= indices[j] + (i - j) + TAIL_GAP
    return False


class JsonLines(NamedTuple):
    """A JSON-lines file read by frame: rows (None for blank, broken or missing lines), each frame's line number in
    the file (0 where no line is), the problems found (one line each) and the numbers of the broken lines."""

    rows: list[dict | None]
    line_numbers: list[int]
    problems: list[str]
    broken: list[int]


def read_jsonl(path: Path) -> tuple[list[dict | None], list[str]]:
    """Rows by frame (None for blank, broken or missing lines) and the problems found, one line each."""
    found = read_jsonl_lines(path)
    return found.rows, found.problems


def read_jsonl_lines(path: Path) -> JsonLines:
    """`read_jsonl` plus each frame's line number and the broken lines (for problem lines)."""
    lines, broken, problems = _parse(path)
    indices = [_frame_index(row) for row in lines]
    frames: dict[int, dict | None] = {}
    numbers: dict[int, int] = {}
    frame = 0
    for i, (row, index) in enumerate(zip(lines, indices)):
        number = i + 1
        if index is not None and index != frame:
            if 0 <= index <= frame + MAX_GAP and _trusted(indices, i):
                problems.append(describe(path, f"line {number}", f"frame_index {index} but the line order gives "
                                         f"{frame} (lines lost, merged or split before it); from here on frames "
                                         "follow frame_index"))
                frame = index
            else:
                problems.append(describe(path, f"line {number}", f"frame_index {index} disagrees with the line order "
                                         f"({frame}); kept in line order"))
        if frames.get(frame) is None:
            frames[frame] = row
            numbers[frame] = number
        elif row is not None:
            problems.append(describe(path, f"line {number}", f"frame {frame} was already read from an earlier line; "
                                     "line ignored"))
        frame += 1
    count = max(frames, default=-1) + 1
    return JsonLines([frames.get(i) for i in range(count)], [numbers.get(i, 0) for i in range(count)], problems, broken)


def json_line(row: dict) -> str:
    """One compact JSON line, newline included."""
    return json.dumps(row, separators=(",", ":")) + "\n"


def where(numbers: list[int]) -> str:
    """`line 4`, or `3 lines, first line 4`."""
    return f"line {numbers[0]}" if len(numbers) == 1 else f"{len(numbers)} lines, first line {numbers[0]}"


class FieldProblems:
    """Collects per-field bad line numbers and reports one summary line per field."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lines: dict[str, tuple[str, list[int]]] = {}

    def add(self, field: str, line: int, what: str) -> None:
        self._lines.setdefault(field, (what, []))[1].append(line)

    def count(self) -> int:
        """How many lines were added, all fields together."""
        return sum(len(numbers) for _, numbers in self._lines.values())

    def lines(self, path: bool = True) -> list[str]:
        """One line per field, the first line's `what` and where (`path`: the file named first)."""
        return [describe(self.path, field, f"{what} ({where(numbers)})") if path else f"{field}: {what} ({where(numbers)})"
                for field, (what, numbers) in self._lines.items()]
