"""What a Rerun recording costs the live path: the simulated rig (scenes/sim.toml) through the live engine
(bundled nano, torch fp32, three views), with and without `--rerun`, in one process, in alternating segments
(so that a change in the machine's load hits both alike); then one long run with the recording on, minute by
minute (resident memory, the file's size, the logger's drops).

    python benchmarks/rerun_live.py [--segment 60] [--rounds 2] [--minutes 30] [--json docs/bench/rerun_live.json]
                                    [--md docs/bench/rerun_live.md]

Per segment: capture-to-prediction latency p50/p99 of every prediction (the engine's own callback), the
engine's rate and drops, and with the recording: items logged and dropped, the logging thread's time per item,
the file's growth in MB per minute.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from report_files import add_report_arguments, machine, write_report  # benchmarks/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]


def partial_path(rrd: Path) -> Path:
    """Where the recording of this process is written until it is renamed into `rrd`."""
    from touchanything.core.temporary_files import temporary_path

    return temporary_path(rrd)


def resident_mb() -> float:
    return int(Path("/proc/self/statm").read_text().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def open_session(rrd: Path | None):
    """The live session of scenes/sim.toml (started), with a Rerun recording into `rrd` when given."""
    from touchanything.app.commands.live_command import open_live_session
    from touchanything.app.sessions.rerun_output import LIVE_IMAGE_SCALE, open_recording
    from touchanything.app.sessions.rerun_sink import RerunSink, seconds_since_first
    from touchanything.viz.rerun_recording import RerunTarget

    session = open_live_session(ROOT / "scenes" / "sim.toml", device="cpu")
    latencies: list[float] = []
    engine_callback = session.live.on_prediction

    def on_prediction(prediction) -> None:
        latencies.append(prediction.latency_ms)
        engine_callback(prediction)

    session.live.on_prediction = on_prediction
    recording = None
    if rrd is not None:
        recording = open_recording(RerunTarget(rrd, image_scale=LIVE_IMAGE_SCALE), "benchmark", {})
        session.rerun = RerunSink(recording, session.bend, seconds_since_first())
    session.start()
    return session, recording, latencies


def segment(seconds: float, rrd: Path | None) -> dict:
    """One run of `seconds` (the first 5 s are warm-up and not counted)."""
    session, recording, latencies = open_session(rrd)
    try:
        time.sleep(5)
        start, processed, dropped = len(latencies), session.live.stats.processed, session.live.stats.dropped
        size0 = partial_path(rrd).stat().st_size if rrd is not None else 0
        time.sleep(seconds)
        window = np.array(latencies[start:])
        row = {"rerun": rrd is not None, "seconds": seconds, "predictions": len(window),
               "engine_fps": (session.live.stats.processed - processed) / seconds,
               "engine_dropped": session.live.stats.dropped - dropped,
               "latency_p50_ms": float(np.percentile(window, 50)), "latency_p99_ms": float(np.percentile(window, 99))}
        if rrd is not None:
            size = partial_path(rrd).stat().st_size
            row["rrd_mb_per_minute"] = (size - size0) / 1e6 * 60 / seconds
    finally:
        session.close()
        if recording is not None:
            recording.close()
    if rrd is not None:
        row |= {"logged": session.rerun.logged, "log_dropped": session.rerun.dropped,
                "log_ms_per_item": 1e3 * session.rerun.busy_s / max(session.rerun.logged, 1)}
    return row


def long_run(minutes: int, rrd: Path, progress) -> list[dict]:
    """The recording on for `minutes`: per minute resident memory, file size, logger counters, latency."""
    session, recording, latencies = open_session(rrd)
    partial, rows, seen = partial_path(rrd), [], 0
    try:
        for minute in range(1, minutes + 1):
            time.sleep(60)
            window = np.array(latencies[seen:])
            seen = len(latencies)
            rows.append({"minute": minute, "rss_mb": resident_mb(), "rrd_mb": partial.stat().st_size / 1e6,
                         "logged": session.rerun.logged, "log_dropped": session.rerun.dropped,
                         "latency_p50_ms": float(np.percentile(window, 50)) if window.size else None,
                         "latency_p99_ms": float(np.percentile(window, 99)) if window.size else None})
            progress(json.dumps(rows[-1]))
    finally:
        session.close()
        recording.close()
    return rows


def markdown(record: dict) -> str:
    lines = ["# Rerun recording on the live path (simulated rig, nano, torch fp32 on the CPU)", "",
             f"{record['machine']}; load average at the start {record['load']}; `{record['command']}`.", "",
             "| segment | rerun | latency p50 ms | latency p99 ms | engine fps | engine drops | MB per minute | "
             "logged | logger drops | ms per logged item |", "|---|---|---|---|---|---|---|---|---|---|"]
    for k, r in enumerate(record["segments"], 1):
        extra = (f"{r['rrd_mb_per_minute']:.1f} | {r['logged']} | {r['log_dropped']} | {r['log_ms_per_item']:.1f}"
                 if r["rerun"] else "– | – | – | –")
        lines.append(f"| {k} | {'on' if r['rerun'] else 'off'} | {r['latency_p50_ms']:.1f} | {r['latency_p99_ms']:.1f} | "
                     f"{r['engine_fps']:.1f} | {r['engine_dropped']} | {extra} |")
    if record["minutes"]:
        lines += ["", "Long run with the recording on:", "", "| minute | RSS MB | rrd MB | logged | logger drops | "
                  "latency p50 ms | latency p99 ms |", "|---|---|---|---|---|---|---|"]
        for r in record["minutes"]:
            lines.append(f"| {r['minute']} | {r['rss_mb']:.0f} | {r['rrd_mb']:.0f} | {r['logged']} | {r['log_dropped']} | "
                         f"{r['latency_p50_ms']:.1f} | {r['latency_p99_ms']:.1f} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segment", type=float, default=60.0, help="seconds per segment")
    parser.add_argument("--rounds", type=int, default=2, help="off/on pairs")
    parser.add_argument("--minutes", type=int, default=0, help="then a long run with the recording on")
    add_report_arguments(parser)
    args = parser.parse_args()
    record = {"machine": machine(),
              "load": " ".join(f"{x:.1f}" for x in os.getloadavg()),
              "command": "python benchmarks/rerun_live.py " + " ".join(sys.argv[1:]), "segments": [], "minutes": []}
    with tempfile.TemporaryDirectory(prefix="touchanything-rerun-") as folder:
        for k in range(args.rounds):
            for rrd in (None, Path(folder) / f"segment{k}.rrd"):
                record["segments"].append(segment(args.segment, rrd))
                print(json.dumps(record["segments"][-1]), file=sys.stderr, flush=True)
        if args.minutes:
            record["minutes"] = long_run(args.minutes, Path(folder) / "long.rrd",
                                         lambda line: print(line, file=sys.stderr, flush=True))
    write_report(record, markdown(record), args.json, args.md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
