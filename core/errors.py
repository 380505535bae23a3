"""User-facing errors: the command line prints their message as one line, without a traceback."""
from __future__ import annotations

import math
from pathlib import Path


class UserError(Exception):
    """A problem with the user's input (path, file contents, option, absent device)."""


def describe(path: str | Path, field: str | None, problem: str) -> str:
    """One line naming the file, the field (when there is one) and what is wrong."""
    return f"{path}: {field}: {problem}" if field else f"{path}: {problem}"


class DataError(UserError):
    """A file that is missing, unreadable, or holds a field of the wrong shape, dtype or value. Pickles (a worker
    process of a batch raises it to the parent)."""

    def __init__(self, path: str | Path, field: str | None, problem: str) -> None:
        super().__init__(describe(path, field, problem))
        self.path = Path(path)
        self.field = field
        self.problem = problem

    def __reduce__(self):
        return DataError, (self.path, self.field, self.problem)


def failure_line(source: str | Path, exc: BaseException) -> str:
    """One line for an item of a batch that failed with any exception: a UserError's own message (it names
    the file), else the item, the exception's type and the first line of its message."""
    if isinstance(exc, UserError):
        return str(exc)
    text = str(exc).strip().splitlines()
    return f"{source}: {exc.__class__.__name__}: {text[0]}" if text else f"{source}: {exc.__class__.__name__}"


class DeviceAlreadyConnectedError(UserError):
    """`connect()` on a device that is already connected: disconnect it first."""


class DeviceNotConnectedError(UserError):
    """An operation that needs a connected device (its bound address, its negotiated format) was asked of
    one that is not connected: connect it first."""


def require_finite_positive(name: str, value: float) -> float:
    """`value` when it is a finite number > 0; else UserError naming the setting (`--seconds`, say) and value."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise UserError(f"{name} must be a finite number > 0, got {value}")
    return value


MAX_SEED = 2**32 - 1
"""The largest seed a command takes (every numpy generator, the legacy one included, takes 0 … 2³² − 1)."""


def require_seed(name: str, value: int) -> int:
    """`value` when it is a whole number 0 … MAX_SEED; else UserError naming the setting and value."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        raise UserError(f"{name} must be an integer 0–{MAX_SEED}, got {value}")
    return value


def require_fraction(name: str, value: float) -> float:
    """`value` when it is a number in [0, 1]; else UserError naming the setting and value (NaN is refused)."""
    if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
        raise UserError(f"{name} must be a number in [0, 1], got {value}")
    return value


class Terminated(BaseException):
    """The process was asked to stop by a signal (SIGTERM): raised in the main thread, like KeyboardInterrupt for
    Ctrl-C, so that every half-written output is removed on the way out (`app.cli.main` installs the handler)."""
