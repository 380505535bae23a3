"""The display yields the CPU to the model it shows. Without a GPU, OpenGL is drawn by Mesa's software
rasterizer (llvmpipe: Xvfb, a remote X session, a machine without a GPU driver), in threads of this process that
take about a third of a core at 30 frames/s; at normal priority they take the engine's time on a busy machine
(the engine's thread runs at nice ENGINE_NICENESS, below capture and the rig clock). Lowered below the engine,
the engine and the player run first under load and the display drops frames instead of the engine dropping
predictions. With a GPU driver there are no such threads and nothing changes."""
from __future__ import annotations

import os

from touchanything.inference.engine.live_engine import ENGINE_NICENESS

RASTERIZER_THREADS = ("llvmpipe",)
"""Name prefixes of the software rasterizer's threads (Linux thread names, /proc/self/task/*/comm)."""
RASTERIZER_NICE = ENGINE_NICENESS + 4
"""The rasterizer threads' nice value, below the engine's (CFS gives a thread 4 nice steps higher in priority
about 2.4× the share)."""


def lower_rasterizer_threads(nice: int = RASTERIZER_NICE) -> int:
    """Set this process's software-rasterizer threads to `nice` (never raising one that is already lower in
    priority); returns how many threads it changed. 0 where there are none or no /proc (not Linux)."""
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return 0
    changed = 0
    for task in tasks:
        try:
            with open(f"/proc/self/task/{task}/comm") as comm:
                name = comm.read().strip()
            if name.startswith(RASTERIZER_THREADS) and os.getpriority(os.PRIO_PROCESS, int(task)) < nice:
                os.setpriority(os.PRIO_PROCESS, int(task), nice)
                changed += 1
        except OSError:  # the thread ended meanwhile, or the system refuses: the display keeps its priority
            continue
    return changed
