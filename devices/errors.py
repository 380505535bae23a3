"""User-facing errors: the command line prints their message as one line, without a traceback."""
from __future__ import annotations

from pathlib import Path


class UserError(Exception):
    """A problem with the user's input (path, file contents, option, absent device)."""


def describe(path: str | Path, field: str | None, problem: str) -> str:
    """One line naming the file, the field (when there is one) and what is wrong."""
    return f"{path}: {field}: {problem}" if field else f"{path}: {problem}"


class DataError(UserError):
    """A file that is missing, unreadable, or holds a field of the wrong shape, dtype or value."""

    def __init__(self, path: str | Path, field: str | None, problem: str) -> None:
        super().__init__(describe(path, field, problem))
        self.path = Path(path)
        self.field = field
        self.problem = problem


class DeviceAlreadyConnectedError(UserError):
    """`connect()` on a device that is already connected: disconnect it first."""


class DeviceNotConnectedError(UserError):
    """An operation that needs a connected device (its bound address, its negotiated format) was asked of
    one that is not connected: connect it first."""
