"""The X display check that must run before dearpygui creates a viewport."""
from __future__ import annotations

import shutil
import subprocess
import time
from pathlib import Path

import pytest

from viz.display import display_problem


def test_missing_or_malformed_displays_are_named(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    assert "DISPLAY is not set" in display_problem()
    assert "not a valid X display" in display_problem("nonsense")
    assert "not reachable" in display_problem(":987")
    assert "not reachable" in display_problem("127.0.0.1:987", timeout=0.5)


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="Xvfb is not installed")
def test_a_running_xvfb_is_reachable():
    number = 93
    server = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", "320x240x24"], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not Path(f"/tmp/.X11-unix/X{number}").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert display_problem(f":{number}") is None
    finally:
        server.terminate()
        server.wait(5)
