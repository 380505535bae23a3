"""Keep a native library's own complaints off the terminal where the project says what happened itself: its
C/C++ code writes to file descriptor 2 directly, past Python's sys.stderr (`quiet_stderr`), or through its own
logger (`quiet_opencv`)."""
from __future__ import annotations

import contextlib
import os
import tempfile
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def quiet_stderr() -> Iterator[None]:
    """File descriptor 2 on /dev/null for the duration; restored afterwards, also on an exception."""
    saved = os.dup(2)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


@contextlib.contextmanager
def captured_stderr() -> Iterator[list[str]]:
    """File descriptor 2 into a private file for the duration; the yielded list receives its lines (stripped,
    empty ones left out) when the block ends, so the caller can say what the library said in its own words."""
    lines: list[str] = []
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as capture:
            os.dup2(capture.fileno(), 2)
            try:
                yield lines
            finally:
                os.dup2(saved, 2)
                capture.seek(0)
                lines += [t for line in capture.read().decode(errors="replace").splitlines() if (t := line.strip())]
    finally:
        os.close(saved)


class _OpenCVQuiet:
    """How many threads are inside `quiet_opencv` now, and OpenCV's log level from before the first one."""

    lock = threading.Lock()
    depth = 0
    level = 0


@contextlib.contextmanager
def quiet_opencv() -> Iterator[None]:
    """OpenCV's logging silenced for the duration (a camera that does not open warns on stderr before the
    caller can say so in one line), then its level from before restored: when the last of several threads
    (cameras opened at once) leaves, also on an exception."""
    import cv2  # imported where used: the commands that never open a camera do not load OpenCV for this

    with _OpenCVQuiet.lock:
        if _OpenCVQuiet.depth == 0:
            _OpenCVQuiet.level = cv2.utils.logging.getLogLevel()
            cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        _OpenCVQuiet.depth += 1
    try:
        yield
    finally:
        with _OpenCVQuiet.lock:
            _OpenCVQuiet.depth -= 1
            if _OpenCVQuiet.depth == 0:
                cv2.utils.logging.setLogLevel(_OpenCVQuiet.level)
