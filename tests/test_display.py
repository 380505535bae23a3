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
