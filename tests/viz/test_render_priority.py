"""The dashboard's software-OpenGL rasterizer threads run below the engine (viz/dashboard/render_priority.py): real
OS threads named as Mesa names llvmpipe's, and the scheduler's own nice values."""
from __future__ import annotations

import os
import threading

from touchanything.inference.engine.live_engine import ENGINE_NICENESS
from touchanything.viz.dashboard.render_priority import lower_rasterizer_threads


class NamedThread:
    """A thread that gives itself an OS name (its /proc comm, as a native library's thread has) and waits."""

    def __init__(self, name: str, nice: int | None = None) -> None:
        self._ready, self._stop = threading.Event(), threading.Event()
        self.tid = 0
        self._thread = threading.Thread(target=self._run, args=(name, nice), daemon=True)
        self._thread.start()
        assert self._ready.wait(5)

    def _run(self, name: str, nice: int | None) -> None:
        self.tid = threading.get_native_id()
        with open(f"/proc/self/task/{self.tid}/comm", "w") as comm:
            comm.write(name)
        if nice is not None:
            os.setpriority(os.PRIO_PROCESS, self.tid, nice)
        self._ready.set()
        self._stop.wait(30)

    @property
    def nice(self) -> int:
        return os.getpriority(os.PRIO_PROCESS, self.tid)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5)


def test_the_rasterizer_threads_go_below_the_engine_and_no_other_thread_moves():
    base = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    rasterizer, decoder, lower_already = NamedThread("llvmpipe-7"), NamedThread("av:h264:df0"), NamedThread("llvmpipe-8", 15)
    try:
        assert lower_rasterizer_threads() >= 1
        assert rasterizer.nice == 12 > ENGINE_NICENESS == 8
        assert decoder.nice == base and os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == base
        assert lower_already.nice == 15, "a thread already lower in priority is never raised"
        assert lower_rasterizer_threads() == 0, "once lowered, nothing changes again"
    finally:
        for thread in (rasterizer, decoder, lower_already):
            thread.stop()
