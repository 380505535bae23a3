"""Command line and session wiring for TouchAnything Live."""
