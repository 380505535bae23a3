"""The ending the benchmarks share: `--json` and `--md` arguments, the machine line of the record, and writing
the record as JSON and its Markdown report (each when asked) and printing the report.

Imported by the benchmark scripts as `from report_files import …` (benchmarks/ is the script's folder).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """`--json PATH` and `--md PATH`: where `write_report` writes the record and its report."""
    parser.add_argument("--json", type=Path)
    parser.add_argument("--md", type=Path)


def machine() -> str:
    """The record's "machine": the CPU cores, the architecture and the Python version."""
    return f"{os.cpu_count()} CPU cores ({platform.machine()}), Python {platform.python_version()}"


def write_report(record: dict, report: str, json_path: Path | None, md_path: Path | None) -> None:
    """Write `record` as indented JSON to `json_path` and the Markdown `report` to `md_path` (each only when
    given, making its folder), then print the report."""
    for path, text in ((json_path, json.dumps(record, indent=1) + "\n"), (md_path, report)):
        if path:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
    print(report)
