"""Reading and writing one section of an official-structure config as a frozen dataclass.

A section class names its keys exactly as the official YAML does. Its fields are the keys this project
reads (typed; `limits(...)` in a field's metadata gives the allowed range; a nested dataclass is a nested
section; `Section | None` with `omit_none` in its metadata is an optional section: absent or null gives None,
which is not written back). Class attributes say what else the official structure may carry there:
- `FIXED`: keys with the one value this model supports (e.g. `type: transformer`): any other value is an error;
- `DERIVED`: keys whose value follows from the fields (e.g. `embed_dim` from the backbone): checked, written;
- `UNUSED`: official keys that do not shape this project's model or run (accepted, reported as unused);
- `ELSEWHERE`: keys another section class reads from the same mapping.
A key that is none of these is an error naming it and the file (in strict sections), so a misspelt or
misplaced setting never silently falls back to a default.
"""
from __future__ import annotations

import math
import types
import typing
from dataclasses import fields, is_dataclass
from typing import Any

from touchanything.core.errors import UserError, describe


def limits(low: float | None = None, high: float | None = None, high_open: bool = False) -> dict:
    """Field metadata: the value (each element of a tuple) must lie in [low, high] (or [low, high))."""
    return {"low": low, "high": high, "high_open": high_open}


def _type_name(kind) -> str:
    return {int: "a whole number", float: "a number", bool: "true or false", str: "a string"}.get(kind, str(kind))


class SectionReader:
    """Reads sections of one config; `unused` collects the dotted names of accepted-but-unused keys."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.unused: list[str] = []

    def error(self, key: str, problem: str) -> UserError:
        return UserError(describe(self.source, key, problem))

    def read(self, cls: type, raw: Any, where: str, strict: bool = True):
        """The section at dotted path `where` (None or absent: all defaults) as an instance of `cls`."""
        if raw is None:
            raw = {}
        if not isinstance(raw, dict):
            raise self.error(where, f"expected a mapping of settings, got {raw!r}")
        hints = typing.get_type_hints(cls)
        known = {f.name: f for f in fields(cls) if not f.metadata.get("not_in_section")}
        values = {}
        for key, value in raw.items():
            name = f"{where}.{key}"
            if key in known:
                values[key] = self._value(hints[key], value, name, known[key].metadata)
            elif key in getattr(cls, "FIXED", {}):
                self._check_fixed(value, cls.FIXED[key], name)
            elif key in getattr(cls, "UNUSED", ()):
                self.unused.append(name)
            elif strict and key not in getattr(cls, "DERIVED", {}) and key not in getattr(cls, "ELSEWHERE", ()):
                raise self.error(name, f"unknown setting (not part of the official config structure under {where})")
        section = cls(**values)
        for key, derive in getattr(cls, "DERIVED", {}).items():
            expected = derive(section)
            if key in raw and expected is not None and raw[key] != expected:
                raise self.error(f"{where}.{key}", f"is {raw[key]!r} but must be {expected!r} for this configuration")
        return section

    def _value(self, kind, value: Any, name: str, metadata) -> Any:
        section = _section_type(kind)
        if section is not None:
            return None if value is None and section is not kind else self.read(section, value, name)
        converted = self._convert(kind, value, name)
        check_limits(converted, metadata, lambda problem: self.error(name, problem))
        return converted

    def _convert(self, kind, value: Any, name: str) -> Any:
        if isinstance(kind, types.UnionType) or typing.get_origin(kind) is typing.Union:
            options = [k for k in typing.get_args(kind) if k is not type(None)]
            return None if value is None else self._convert(options[0], value, name)
        if typing.get_origin(kind) is tuple:
            items = typing.get_args(kind)
            if not isinstance(value, list | tuple) or len(value) != len(items):
                raise self.error(name, f"expected a list of {len(items)} values, got {value!r}")
            return tuple(self._convert(k, v, name) for k, v in zip(items, value))
        if kind is float and isinstance(value, str):
            value = _float_text(value)  # YAML 1.1 reads `1e-6` (no dot) as a string
        ok = {bool: isinstance(value, bool), int: isinstance(value, int) and not isinstance(value, bool),
              float: isinstance(value, int | float) and not isinstance(value, bool), str: isinstance(value, str)}[kind]
        if not ok:
            raise self.error(name, f"expected {_type_name(kind)}, got {value!r}")
        return float(value) if kind is float else value

    def _check_fixed(self, value: Any, expected: Any, name: str) -> None:
        if value != expected:
            raise self.error(name, f"{value!r} is not supported; this model supports only {expected!r}")


def _section_type(kind) -> type | None:
    """The dataclass of a nested section field (`Section` or an optional `Section | None`), else None."""
    if is_dataclass(kind):
        return kind
    if isinstance(kind, types.UnionType) or typing.get_origin(kind) is typing.Union:
        return next((k for k in typing.get_args(kind) if is_dataclass(k)), None)
    return None


def _float_text(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text


def check_limits(value: Any, metadata, fail) -> None:
    """Raise `fail(problem)` when `value` (or an element of a tuple) is not finite or outside its limits."""
    if "low" not in metadata or value is None:
        return
    low, high, high_open = metadata["low"], metadata["high"], metadata["high_open"]
    for item in value if isinstance(value, tuple) else (value,):
        if isinstance(item, float) and not math.isfinite(item):
            raise fail(f"must be a finite number, got {item!r}")
        if low is not None and item < low:
            raise fail(f"must be ≥ {low}, got {item!r}")
        if high is not None and (item >= high if high_open else item > high):
            raise fail(f"must be {'<' if high_open else '≤'} {high}, got {item!r}")


def check_section(section, where: str, source: str = "config") -> None:
    """The limits of every field of a section built in Python (presets, tests), nested sections included."""
    for f in fields(section):
        if f.metadata.get("not_in_section"):
            continue
        value, name = getattr(section, f.name), f"{where}.{f.name}"
        if value is None:
            continue
        if is_dataclass(value):
            check_section(value, name, source)
        else:
            check_limits(value, f.metadata, lambda problem: UserError(describe(source, name, problem)))


def section_to_dict(section) -> dict:
    """The section in the official structure: fixed keys, then the fields, then derived keys."""
    out = dict(getattr(section, "FIXED", {}))
    for f in fields(section):
        value = getattr(section, f.name)
        if f.metadata.get("not_in_section") or (value is None and f.metadata.get("omit_none")):
            continue
        out[f.name] = section_to_dict(value) if is_dataclass(value) else list(value) if isinstance(value, tuple) else value
    out.update({key: derive(section) for key, derive in getattr(section, "DERIVED", {}).items()})
    return out
