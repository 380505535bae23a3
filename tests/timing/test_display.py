"""The X display check that must run before dearpygui creates a viewport."""
from __future__ import annotations

from touchanything.viz.display import display_problem


def test_missing_or_malformed_displays_are_named(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    assert "DISPLAY is not set" in display_problem()
    assert "not a valid X display" in display_problem("nonsense")
    assert "not reachable" in display_problem(":987")
    assert "not reachable" in display_problem("127.0.0.1:987", timeout=0.5)


def test_the_test_display_is_reachable(x_display):
    assert display_problem(x_display) is None


def test_a_server_that_refuses_the_client_is_one_line(tmp_path, monkeypatch, capfd):
    """An X server that requires a cookie the client lacks: the check says so (nothing on stderr) instead of
    letting dearpygui abort the process; with the cookie the display opens."""
    import shutil
    import subprocess
    import time

    import pytest

    from conftest import _free_display_number

    if shutil.which("Xvfb") is None or shutil.which("xauth") is None:
        pytest.skip("Xvfb and xauth are needed (apt-get install xvfb xauth)")
    display, cookies = f":{_free_display_number()}", tmp_path / "Xauthority"
    subprocess.run(["xauth", "-f", str(cookies), "add", display, ".", "0123456789abcdef0123456789abcdef"], check=True)
    server = subprocess.Popen(["Xvfb", display, "-auth", str(cookies), "-nolisten", "tcp", "-noreset"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        monkeypatch.setenv("XAUTHORITY", str(tmp_path / "no_cookies"))
        deadline = time.monotonic() + 15
        while "not reachable" in (display_problem(display) or "not reachable"):
            assert server.poll() is None and time.monotonic() < deadline, f"Xvfb {display} did not start"
            time.sleep(0.05)
        capfd.readouterr()
        refused = display_problem(display)  # Xlib's own reason, said in the line instead of on stderr
        assert refused.startswith(f"X display {display} refused the connection: Authorization required"), refused
        assert capfd.readouterr().err == ""
        monkeypatch.setenv("XAUTHORITY", str(cookies))
        assert display_problem(display) is None
    finally:
        server.terminate()
        server.wait(5)
