"""Starting and stopping the one background thread each device, simulator and the rig clock owns."""
from __future__ import annotations

import threading
from collections.abc import Callable

JOIN_TIMEOUT_S = 5.0
"""Stopping waits this long for the thread; one stuck in a driver call is then left behind (a daemon
thread) rather than hanging the shutdown."""


def start_worker(target: Callable[[], None], name: str, release: Callable[[], None] = lambda: None) -> threading.Thread:
    """A started daemon thread running `target`; when it cannot start, `release()` frees what the caller
    opened for it (port, socket) and the error is raised."""
    thread = threading.Thread(target=target, name=name, daemon=True)
    try:
        thread.start()
    except BaseException:
        release()
        raise
    return thread


def stop_worker(thread: threading.Thread | None, stop: threading.Event) -> None:
    """Set `stop` and wait for `thread` (None: nothing is running)."""
    if thread is None:
        return
    stop.set()
    thread.join(JOIN_TIMEOUT_S)
