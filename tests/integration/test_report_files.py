"""The ending the benchmarks share (benchmarks/report_files.py): `--json`/`--md`, the machine line, and the
record written as JSON and Markdown (each only when asked) with the report printed."""
from __future__ import annotations

import argparse
import json
import os
import runpy
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
REPORT = runpy.run_path(str(ROOT / "benchmarks" / "report_files.py"))


def test_the_report_goes_to_the_files_asked_for_and_is_printed(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    REPORT["add_report_arguments"](parser)
    args = parser.parse_args(["--json", str(tmp_path / "new" / "r.json"), "--md", str(tmp_path / "other" / "r.md")])
    record = {"machine": REPORT["machine"](), "rows": [1.5, 2]}
    REPORT["write_report"](record, "# report\n", args.json, args.md)
    assert (tmp_path / "new" / "r.json").read_text() == json.dumps(record, indent=1) + "\n"
    assert (tmp_path / "other" / "r.md").read_text() == "# report\n"
    assert capsys.readouterr().out == "# report\n\n"
    assert record["machine"].startswith(f"{os.cpu_count()} CPU cores (") and ", Python 3." in record["machine"]


def test_without_paths_the_report_is_only_printed(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = argparse.Namespace(json=None, md=None)
    REPORT["write_report"]({"a": 1}, "text", args.json, args.md)
    assert capsys.readouterr().out == "text\n" and not list(tmp_path.iterdir())
