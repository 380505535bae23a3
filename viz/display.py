"""Is an X display reachable? dearpygui aborts the whole process when it is not, so ask before creating a
viewport."""
from __future__ import annotations

import os
import socket

X11_SOCKET_DIR = "/tmp/.X11-unix"
X11_TCP_BASE = 6000


def display_problem(display: str | None = None, timeout: float = 1.0) -> str | None:
    """None when the X display (default: $DISPLAY) accepts a connection; otherwise why not, in one line."""
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
    return None
