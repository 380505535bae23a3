"""Is an X display usable? dearpygui aborts the whole process when it cannot open one, so ask before creating a
viewport: first whether the server's socket answers (bounded by a timeout), then whether the X client library
opens the display as GLFW will (the server may refuse a client it has not authorised)."""
from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import os
import socket

from touchanything.devices.quiet_stderr import captured_stderr

X11_SOCKET_DIR = "/tmp/.X11-unix"
X11_TCP_BASE = 6000


def display_problem(display: str | None = None, timeout: float = 1.0) -> str | None:
    """None when the X display (default: $DISPLAY) can be opened; otherwise why not, in one line."""
    display = os.environ.get("DISPLAY") if display is None else display
    if not display:
        return "no X display: DISPLAY is not set"
    host, colon, rest = display.rpartition(":")
    number = rest.split(".")[0]
    if not colon or not number.isdigit():
        return f"DISPLAY={display!r} is not a valid X display name"
    if host in ("", "unix"):
        family, address = socket.AF_UNIX, f"{X11_SOCKET_DIR}/X{number}"
    else:
        family, address = socket.AF_INET, (host, X11_TCP_BASE + int(number))
    with socket.socket(family, socket.SOCK_STREAM) as connection:
        connection.settimeout(timeout)
        try:
            connection.connect(address)
        except OSError as exc:
            return f"X display {display} is not reachable ({exc.strerror or exc})"
    return _open_problem(display)


def _open_problem(display: str) -> str | None:
    """Open and close `display` with libX11; its own complaint on stderr is kept off the terminal and becomes the
    reason of the one line ("Authorization required, but no authorization protocol specified")."""
    xlib = _xlib()
    if xlib is None:
        return "the X client library libX11 is not installed (apt-get install libx11-6)"
    with captured_stderr() as said:
        handle = xlib.XOpenDisplay(display.encode())
    if not handle:
        reason = "; ".join(said) or "no reason given by libX11"
        return (f"X display {display} refused the connection: {reason} (check XAUTHORITY or the server's xhost "
                "list)")
    xlib.XCloseDisplay(handle)
    return None


@functools.cache
def _xlib() -> ctypes.CDLL | None:
    for name in filter(None, (ctypes.util.find_library("X11"), "libX11.so.6")):
        with contextlib.suppress(OSError, AttributeError):
            xlib = ctypes.CDLL(name)
            xlib.XOpenDisplay.restype, xlib.XOpenDisplay.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
            xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
            return xlib
    return None
