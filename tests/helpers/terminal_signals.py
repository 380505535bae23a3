"""A child process started as from a terminal, whatever the test process's own SIGINT disposition or mask.

A shell without job control starts a background command (`make test &`, a CI runner's step) with SIGINT ignored,
and an ignored signal stays ignored across exec: a child would then outlive every Ctrl-C a test sends it."""
from __future__ import annotations

import signal


def default_sigint() -> None:
    """`preexec_fn`, in the child before exec: SIGINT delivered and handled by default (Python then raises
    KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
