"""Scene values against the types their settings declare: a TOML value of the wrong type is one line naming
the section and the key, before any device is built (`[hands] port: expected a whole number, got 'abc'`)."""
from __future__ import annotations

import dataclasses
import types
import typing
from pathlib import Path
from typing import Any

from touchanything.core.errors import UserError

TYPE_NAMES = {int: "a whole number", float: "a number", str: "text", bool: "true or false", Path: "a path",
              dict: "a table", tuple: "a list", list: "a list"}


def _accepts(hint: Any, value: Any) -> bool:
    """Whether a TOML `value` can stand for a setting declared as `hint` (ints for floats, text for paths,
    lists for tuples, element by element)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(_accepts(arg, value) for arg in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is Path:
        return isinstance(value, str | Path)
    if origin in (tuple, list) or hint in (tuple, list):
        if not isinstance(value, list | tuple):
            return False
        if origin is tuple and args and args[-1] is not Ellipsis:
            return len(args) == len(value) and all(_accepts(a, v) for a, v in zip(args, value))
        return not args or all(_accepts(args[0], v) for v in value)
    if origin is dict or hint is dict:
        return isinstance(value, dict)
    return isinstance(value, hint) if isinstance(hint, type) else True


def _describe(hint: Any) -> str:
    """"a whole number", "a list of 2 (a number, a number)", "text or a whole number", …"""
    origin, args = typing.get_origin(hint), [a for a in typing.get_args(hint) if a is not type(None)]
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(a) for a in args)
    if origin in (tuple, list) and args:
        if origin is tuple and args[-1] is not Ellipsis:
            return f"a list of {len(args)} ({', '.join(_describe(a) for a in args)})"
        return f"a list of ({_describe(args[0])})"
    return TYPE_NAMES.get(origin or hint, getattr(hint, "__name__", str(hint)))


def check_types(cls: type, section: str, settings: dict) -> None:
    """UserError "[section] key: expected …, got …" for the first setting whose value does not fit the type
    the dataclass `cls` declares for it (unknown keys are left to the constructor)."""
    hints = typing.get_type_hints(cls)
    for field in dataclasses.fields(cls):
        if field.name in settings and not _accepts(hints[field.name], settings[field.name]):
            raise UserError(f"[{section}] {field.name}: expected {_describe(hints[field.name])}, "
                            f"got {settings[field.name]!r}")
