"""quiet_stderr: what native code writes to file descriptor 2 is dropped, and the descriptor comes back."""
from __future__ import annotations

import os

import pytest

from touchanything.devices.quiet_stderr import quiet_stderr


def test_writes_to_fd_2_are_dropped_and_fd_2_is_restored_also_after_an_error(capfd):
    with quiet_stderr():
        os.write(2, b"native complaint\n")
    with pytest.raises(RuntimeError), quiet_stderr():
        os.write(2, b"another one\n")
        raise RuntimeError("boom")
    os.write(2, b"visible\n")
    assert capfd.readouterr().err == "visible\n"
