"""A soak of the whole live path: the simulated rig (scenes/sim.toml: JQ gloves on ptys, Rokoko UDP, the camera
videos, the trackers) through the rig clock into the live engine (bundled nano, torch fp32, three views), the
dashboard's state polled at 30 Hz as the dashboard does (no window), and the recorder writing the session.

    python benchmarks/soak.py [--minutes 30] [--row-seconds 60] [--json docs/bench/soak.json] [--md docs/bench/soak.md]

Per minute (a row of `--row-seconds`, 60 by default; the test suite's short soak uses shorter rows):
resident memory, capture-to-prediction latency p50/p99 of the predictions the dashboard saw,
engine drops, recorder drops, rig-clock skipped ticks, open file descriptors and threads. Targets: memory
growth ≤ 50 MB after the first minute, latency p99 and thread / fd counts flat, recorder drops 0.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from report_files import add_report_arguments, machine, write_report  # benchmarks/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]
POLL_HZ = 30
MEMORY_GROWTH_MB = 50.0


def resident_mb() -> float:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def open_fds() -> int:
    return len(os.listdir("/proc/self/fd"))


class MinuteCounters:
    """Cumulative counters of the session, read as differences per minute."""

    def __init__(self, session) -> None:
        self.session = session
        self.last = self.read()

    def read(self) -> dict[str, int]:
        s = self.session
        return {"engine_dropped": s.live.stats.dropped, "engine_processed": s.live.stats.processed,
                "recorder_dropped": s.recorder.counters.dropped, "recorder_written": s.recorder.counters.written,
                "clock_skipped": s.rig.clock.counters.skipped, "clock_ticks": s.rig.clock.counters.ticks}

    def minute(self) -> dict[str, int]:
        now = self.read()
        delta = {key: now[key] - self.last[key] for key in now}
        self.last = now
        return delta


def soak(minutes: int, progress=print, row_seconds: float = 60.0) -> dict:
    """Run the live path for `minutes` rows of `row_seconds` each; returns {"minutes": [row per minute],
    "summary": {...}}."""
    from touchanything.app.commands.live_command import open_live_session

    with tempfile.TemporaryDirectory(prefix="touchanything-soak-") as folder:
        session = open_live_session(ROOT / "scenes" / "sim.toml", device="cpu")
        session.recordings_dir = Path(folder)
        session.start()
        session.toggle_recording()
        if session.recorder is None:
            raise SystemExit(f"could not start recording: {session.message}")
        counters, rows, seen = MinuteCounters(session), [], -1
        try:
            for index in range(minutes):
                latencies, end = [], time.monotonic() + row_seconds
                while time.monotonic() < end:
                    prediction = session.state().prediction
                    if prediction is not None and prediction.frame_index != seen:
                        seen = prediction.frame_index
                        latencies.append(prediction.latency_ms)
                    time.sleep(1 / POLL_HZ)
                row = {"minute": index + 1, "rss_mb": resident_mb(), "fds": open_fds(),
                       "threads": threading.active_count(), "predictions_seen": len(latencies),
                       "latency_p50_ms": float(np.percentile(latencies, 50)) if latencies else None,
                       "latency_p99_ms": float(np.percentile(latencies, 99)) if latencies else None,
                       **counters.minute()}
                rows.append(row)
                progress(json.dumps(row))
        finally:
            session.close()
    return {"minutes": rows, "summary": summarise(rows)}


def summarise(rows: list[dict]) -> dict:
    """Growth after the first minute and the spread of the per-minute figures, with the targets."""
    after = rows[1:] or rows
    growth = max(r["rss_mb"] for r in after) - rows[0]["rss_mb"]
    p99 = [r["latency_p99_ms"] for r in rows if r["latency_p99_ms"] is not None]
    return {"memory_growth_after_first_minute_mb": growth, "memory_target_mb": MEMORY_GROWTH_MB,
            "memory_met": growth <= MEMORY_GROWTH_MB,
            "threads": sorted({r["threads"] for r in rows}), "fds": sorted({r["fds"] for r in rows}),
            "latency_p99_first_last_ms": [p99[0], p99[-1]] if p99 else None,
            "recorder_dropped": sum(r["recorder_dropped"] for r in rows),
            "engine_dropped": sum(r["engine_dropped"] for r in rows),
            "clock_skipped": sum(r["clock_skipped"] for r in rows)}


def markdown(record: dict) -> str:
    s = record["summary"]
    lines = ["# Soak: simulated rig + engine + dashboard state + recorder", "",
             f"{record['machine']}; {len(record['minutes'])} minutes; `{record['command']}`.", "",
             "| minute | RSS MB | latency p50 ms | latency p99 ms | engine drops | recorder drops | clock skipped | fds | "
             "threads |", "|---|---|---|---|---|---|---|---|---|"]
    for r in record["minutes"]:
        p50 = "n/a" if r["latency_p50_ms"] is None else f"{r['latency_p50_ms']:.0f}"
        p99 = "n/a" if r["latency_p99_ms"] is None else f"{r['latency_p99_ms']:.0f}"
        lines.append(f"| {r['minute']} | {r['rss_mb']:.0f} | {p50} | {p99} | {r['engine_dropped']} | "
                     f"{r['recorder_dropped']} | {r['clock_skipped']} | {r['fds']} | {r['threads']} |")
    lines += ["", f"Memory growth after the first minute: {s['memory_growth_after_first_minute_mb']:.1f} MB "
              f"(target ≤ {s['memory_target_mb']:.0f} MB: {'met' if s['memory_met'] else '**not met**'}); threads "
              f"{s['threads']}, fds {s['fds']}; recorder drops {s['recorder_dropped']}; engine drops "
              f"{s['engine_dropped']} (live mode drops by design); rig-clock skipped ticks {s['clock_skipped']}."]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=int, default=30)
    parser.add_argument("--row-seconds", type=float, default=60.0, help="length of a row (default 60: a row a minute)")
    add_report_arguments(parser)
    args = parser.parse_args()
    if args.minutes < 1 or not 1 <= args.row_seconds <= 3600:  # also NaN
        parser.error(f"--minutes must be ≥ 1 and --row-seconds 1–3600, got {args.minutes} and {args.row_seconds}")
    record = soak(args.minutes, lambda line: print(line, file=sys.stderr, flush=True), args.row_seconds)
    record.update(machine=machine(),
                  command="python benchmarks/soak.py " + " ".join(sys.argv[1:]))
    write_report(record, markdown(record), args.json, args.md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
