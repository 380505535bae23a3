"""How fast the command line answers: `touchanything --help`, `touchanything COMMAND --help` for every
command, and `info` of one raw episode of the bundled sample, each run RUNS times in a fresh process.

    python benchmarks/cli_startup.py [--runs 5] [--out docs/bench/cli_startup]

Reports the minimum and median wall time of each (the minimum is the figure: other jobs on the machine only add
to it) and the minimum CPU time (user + system) of the process, against its target. Writes OUT.json and OUT.md;
exit status 1 when a target is missed.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from touchanything.app.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
TOUCHANYTHING = ROOT / ".venv" / "bin" / "touchanything"
EPISODE = ROOT / "recordings" / "sample" / "Home" / "slide_box_cardboard" / "sim0007_00000"
HELP_TARGET_S = 0.5
INFO_TARGET_S = 1.5


def commands() -> list[str]:
    """Every sub-command's name, as `touchanything --help` lists them."""
    subparsers = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return list(subparsers.choices)


def measured() -> list[tuple[list[str], float]]:
    """(arguments, target s) of each measured command."""
    return ([(["--help"], HELP_TARGET_S)] + [([name, "--help"], HELP_TARGET_S) for name in commands()]
            + [(["info", str(EPISODE.relative_to(ROOT))], INFO_TARGET_S)])


def timed(arguments: list[str]) -> tuple[float, float]:
    """(wall s, CPU s) of one `touchanything ARGUMENTS` in a fresh process (it must succeed)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    began = time.perf_counter()
    subprocess.run([str(TOUCHANYTHING), *arguments], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - began
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def markdown(record: dict) -> str:
    lines = ["# Command-line start-up (`benchmarks/cli_startup.py`)", "",
             f"Each command run {record['runs']} times in a fresh process on {record['machine']}; load average "
             f"{record['load_average'][0]:.1f} before and {record['load_average'][1]:.1f} after (other jobs on the machine "
             "only add to the wall time: the minimum is the figure).", "",
             "| command | min s | median s | min CPU s | target s | met |", "|---|---|---|---|---|---|"]
    for row in record["rows"]:
        lines.append(f"| `touchanything {row['command']}` | {row['min_s']:.2f} | {row['median_s']:.2f} | "
                     f"{row['min_cpu_s']:.2f} | ≤ {row['target_s']} | {'yes' if row['met'] else '**no**'} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="fresh processes per command (default 5)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench" / "cli_startup",
                        help="writes OUT.json and OUT.md (default docs/bench/cli_startup)")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    rows = []
    for arguments, target in measured():
        walls, cpus = zip(*(timed(arguments) for _ in range(args.runs)))
        row = {"command": " ".join(arguments), "min_s": min(walls), "median_s": statistics.median(walls),
               "min_cpu_s": min(cpus), "target_s": target, "met": min(walls) <= target, "wall_s": walls}
        rows.append(row)
        print(f"{row['command']:<70} min {row['min_s']:.2f} s  median {row['median_s']:.2f} s  CPU {row['min_cpu_s']:.2f} s",
              file=sys.stderr)
    record = {"runs": args.runs, "machine": f"{os.cpu_count()} CPU cores ({platform.machine()}), Python "
              f"{platform.python_version()}", "load_average": [load_before, os.getloadavg()[0]], "rows": rows}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(record, indent=1) + "\n")
    args.out.with_suffix(".md").write_text(markdown(record))
    print(markdown(record))
    return 0 if all(row["met"] for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
