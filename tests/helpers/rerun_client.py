"""Rerun's own client (`rerun URL --save FILE`) following a served recording, as a test's independent reader.

The client is a wrapper script that starts the viewer binary; the binary also listens for SDK connections on a
port of its own (9876 unless told). Each client here gets a port the OS has just given out, and its own process
group, so that stopping it stops the binary too: an orphaned binary on 9876 made every later client fail to start
and save nothing."""
from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

from helpers.terminal_signals import default_sigint

RERUN = Path(sys.executable).parent / "rerun"


def free_port() -> int:
    """A TCP port on 127.0.0.1 the OS has just given out (free a moment ago)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@contextlib.contextmanager
def rerun_client(data_url: str, out: Path) -> Iterator[subprocess.Popen]:
    """The client saving what `data_url` serves into `out`, running for the `with` block; on leaving, its whole
    process group is killed (whatever it did: the caller waits for a clean end inside the block)."""
    client = subprocess.Popen([str(RERUN), data_url, "--save", str(out), "--port", str(free_port())],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                              preexec_fn=default_sigint)
    try:
        yield client
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(client.pid, signal.SIGKILL)
        client.wait()


def interrupt(client: subprocess.Popen) -> None:
    """Ctrl-C to the client's process group (the wrapper and the binary), as in a terminal."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(client.pid, signal.SIGINT)
