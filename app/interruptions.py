"""How a command stops when asked to: Ctrl-C (SIGINT) raises KeyboardInterrupt and SIGTERM raises `Terminated` in the
main thread, so that every output being written is removed on the way out (`core.output_safety`).

Python runs a signal's handler between two steps of whatever the main thread executes — also inside a weak
reference's callback or a finaliser, where an exception cannot propagate and is swallowed ("Exception ignored
in …"), and the command would go on. h5py and PyAV keep such callbacks busy: a conversion spends most of its
Python time in `WeakValueDictionary` removals, so most interruptions landed there. So a signal that arrives inside
a weak reference's callback is not raised there but sent again a moment later, from another thread; and one that
was swallowed anyway (another callback) reaches `sys.unraisablehook`, which sends it again the same way.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

from touchanything.core.errors import Terminated

RAISED = {signal.SIGINT: KeyboardInterrupt, signal.SIGTERM: Terminated}
AGAIN_AFTER_S = 0.005


@contextlib.contextmanager
def stoppable() -> Iterator[None]:
    """SIGINT and SIGTERM raise in the main thread as described above while the block runs (main thread only)."""
    previous = {signum: signal.signal(signum, _raise) for signum in RAISED}
    previous_hook, sys.unraisablehook = sys.unraisablehook, _swallowed
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        sys.unraisablehook = previous_hook


def _again(signum: int) -> None:
    threading.Timer(AGAIN_AFTER_S, os.kill, (os.getpid(), signum)).start()


def _raise(signum: int, frame) -> None:
    if frame is not None and frame.f_code.co_filename.endswith(f"{os.sep}weakref.py"):
        _again(signum)  # raised here, it would be swallowed
        return
    raise RAISED[signum]


def _swallowed(unraisable) -> None:
    for signum, kind in RAISED.items():
        if isinstance(unraisable.exc_value, kind):
            _again(signum)
            return
    sys.__unraisablehook__(unraisable)
