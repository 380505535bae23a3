"""JSON-lines files: one object per line, the line number is the frame index (blank lines count).

A broken line never shifts later frames: it becomes an empty row and a problem naming its line number.
"""
from __future__ import annotations

import json
from pathlib import Path

from touchanything.devices.errors import DataError, describe


def read_jsonl(path: Path) -> tuple[list[dict | None], list[str]]:
    """Rows (None for blank or broken lines) and the problems found, one line each."""
    rows: list[dict | None] = []
    problems: list[str] = []
    try:
        handle = open(path, "rb")
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except OSError as exc:
        raise DataError(path, None, f"cannot open ({exc.strerror})") from None
    with handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text:
                rows.append(None)
                continue
            try:
                obj = json.loads(text)
            except (UnicodeDecodeError, ValueError) as exc:
                reason = exc.msg if isinstance(exc, json.JSONDecodeError) else "not UTF-8 text"
                problems.append(describe(path, f"line {number}", f"invalid JSON ({reason}); frame left empty"))
                rows.append(None)
                continue
            if not isinstance(obj, dict):
                problems.append(describe(path, f"line {number}", "not a JSON object; frame left empty"))
                obj = None
            rows.append(obj)
    return rows, problems


def json_line(row: dict) -> str:
    """One compact JSON line, newline included."""
    return json.dumps(row, separators=(",", ":")) + "\n"


class FieldProblems:
    """Collects per-field bad line numbers and reports one summary line per field."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._lines: dict[str, tuple[str, list[int]]] = {}

    def add(self, field: str, line: int, what: str) -> None:
        self._lines.setdefault(field, (what, []))[1].append(line)

    def lines(self) -> list[str]:
        out = []
        for field, (what, numbers) in self._lines.items():
            where = f"line {numbers[0]}" if len(numbers) == 1 else f"{len(numbers)} lines, first line {numbers[0]}"
            out.append(describe(self.path, field, f"{what} ({where})"))
        return out
