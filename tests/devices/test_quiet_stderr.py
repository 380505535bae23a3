"""quiet_stderr: what native code writes to file descriptor 2 is dropped, and the descriptor comes back; quiet_opencv:
OpenCV's logger is silent while any caller is inside, and its level comes back when the last one leaves."""
from __future__ import annotations

import os

import pytest

from touchanything.devices.quiet_stderr import quiet_opencv, quiet_stderr


def test_writes_to_fd_2_are_dropped_and_fd_2_is_restored_also_after_an_error(capfd):
    with quiet_stderr():
        os.write(2, b"native complaint\n")
    with pytest.raises(RuntimeError), quiet_stderr():
        os.write(2, b"another one\n")
        raise RuntimeError("boom")
    os.write(2, b"visible\n")
    assert capfd.readouterr().err == "visible\n"


def test_opencv_is_silent_until_the_last_caller_leaves():
    import cv2

    logging = cv2.utils.logging
    before = logging.getLogLevel()
    logging.setLogLevel(logging.LOG_LEVEL_WARNING)
    try:
        with quiet_opencv():
            with quiet_opencv():  # a second camera opened at the same time
                assert logging.getLogLevel() == logging.LOG_LEVEL_SILENT
            assert logging.getLogLevel() == logging.LOG_LEVEL_SILENT  # the first one is still opening
        assert logging.getLogLevel() == logging.LOG_LEVEL_WARNING
        with pytest.raises(RuntimeError), quiet_opencv():
            raise RuntimeError("boom")
        assert logging.getLogLevel() == logging.LOG_LEVEL_WARNING
    finally:
        logging.setLogLevel(before)
