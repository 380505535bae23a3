"""Benchmark: what the recorder's fsync cadence costs its writer thread, on this machine's disk.

    .venv/bin/python benchmarks/recorder_fsync.py [--seconds 10] [--views 3] [--modes off,1,0.1] [--repeat 1]
                                                  [--dir DIR] [--json FILE]

Records `--seconds` of synthetic 30 Hz Snapshots (textured 640×480 pictures panning on every view, both
hands' joints, both gloves, the chest tracker) through the real `Recorder`, once per fsync mode (`off`:
`fsync_s = None`; a number: `fsync_s` seconds), into a fresh folder under `--dir` (default: the system's
temporary folder; put it on the disk you record to). The writer thread's time per frame is measured: the
frame's `RawEpisodeWriter.write` plus the sync round that followed it, if one did; p50 / p99 / max / total,
then the sync rounds alone (count, p50, p99, total) and what `stop()` took (the last fsyncs and the grids).
Each mode starts from a clean page cache (`os.sync()` before it), so one mode's writeback does not land
on the next; `--repeat R` runs the modes R times in turn (off, 1, 0.1, off, …) and pools each mode's frames,
so a machine whose load changes weighs on every mode alike.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from touchanything.core.snapshot import FPS, VIEW_NAMES, Snapshot
from touchanything.devices.rig.recorder import Recorder, RecorderConfig


class TimedRecorder(Recorder):
    """The Recorder, with the writer thread's two steps timed (the same code runs between the stamps)."""

    def __init__(self, config: RecorderConfig) -> None:
        super().__init__(config)
        self.events: list[tuple[str, float]] = []

    def _write_frame(self, writer, snapshot) -> None:
        began = time.perf_counter()
        super()._write_frame(writer, snapshot)
        self.events.append(("write", time.perf_counter() - began))

    def _sync(self, writer) -> None:
        began = time.perf_counter()
        super()._sync(writer)
        self.events.append(("sync", time.perf_counter() - began))


def snapshots(views: int, seed: int = 0):
    """Snapshot k of an endless synthetic rig (new arrays every frame, as the rig clock makes)."""
    rng = np.random.default_rng(seed)
    texture = rng.integers(0, 256, size=(90, 120, 3), dtype=np.uint8).repeat(8, 0).repeat(8, 1)
    joints = rng.uniform(-3, 3, size=(42, 3)).astype(np.float32)
    joints[:, 2] += 50
    k = 0
    while True:
        images = {}
        for v, name in enumerate(VIEW_NAMES[:views]):
            y, x = (k * 3 + 40 * v) % 240, (k * 5 + 70 * v) % 320
            images[name] = np.ascontiguousarray(texture[y:y + 480, x:x + 640])
        yield Snapshot(frame_index=k, t_us=k * 33_333, images=images, joints=joints + k * 1e-3,
                       joints_valid=np.array([True, True]), mocap_joints=joints, mocap_valid=np.array([True, True]),
                       pressure_raw=rng.integers(0, 60, size=(2, 256), dtype=np.uint8),
                       glove_present=np.array([True, True]),
                       imu_wxyz=np.tile(np.float32([1, 0, 0, 0]), (2, 1)),
                       trackers={"chest": np.float32([0, 1.5, 0, 1, 0, 0, 0])})
        k += 1


def percentiles(values: list[float]) -> dict:
    if not values:
        return {"count": 0}
    ms = np.asarray(values) * 1e3
    return {"count": len(values), "p50_ms": round(float(np.percentile(ms, 50)), 2),
            "p99_ms": round(float(np.percentile(ms, 99)), 2), "max_ms": round(float(ms.max()), 2),
            "total_s": round(float(ms.sum() / 1e3), 3)}


def record(folder: Path, fsync_s: float | None, seconds: float, views: int) -> dict:
    """One recording; the raw timings (seconds) of its frames and sync rounds."""
    os.sync()  # the previous mode's dirty pages are not this one's cost
    recorder = TimedRecorder(RecorderConfig(folder, queue_frames=60, fsync_s=fsync_s))
    source = snapshots(views)
    recorder.start()
    began = time.monotonic()
    for k in range(int(seconds * FPS)):
        time.sleep(max(0.0, began + k / FPS - time.monotonic()))
        recorder.write(next(source))
    stop_began = time.perf_counter()
    counters = recorder.stop()
    stop_s = time.perf_counter() - stop_began
    per_frame: list[float] = []
    syncs: list[float] = []
    for kind, duration in recorder.events:
        if kind == "write":
            per_frame.append(duration)
        else:
            syncs.append(duration)
            if per_frame:
                per_frame[-1] += duration  # the round that followed the frame is that frame's cost
    size = sum(p.stat().st_size for p in folder.iterdir())
    return {"frames": counters.written, "dropped": counters.dropped, "per_frame": per_frame, "syncs": syncs,
            "stop_s": [stop_s], "mb": [size / 1e6]}


def summary(fsync_s: float | None, runs: list[dict]) -> dict:
    """One mode's recordings pooled."""
    pooled = {key: [v for run in runs for v in run[key]] for key in ("per_frame", "syncs", "stop_s", "mb")}
    return {"fsync": "off" if fsync_s is None else f"every {fsync_s:g} s", "runs": len(runs),
            "frames": sum(r["frames"] for r in runs), "dropped": sum(r["dropped"] for r in runs),
            "per_write": percentiles(pooled["per_frame"]), "sync_rounds": percentiles(pooled["syncs"]),
            "stop_s": round(float(np.mean(pooled["stop_s"])), 3), "mb": round(float(np.mean(pooled["mb"])), 1)}


def filesystem_of(path: Path) -> str:
    """The filesystem type and device that holds `path` (from /proc/mounts), for the report."""
    best = ("", "?", "?")
    try:
        for line in Path("/proc/mounts").read_text().splitlines():
            device, mount, kind = line.split()[:3]
            if str(path.resolve()).startswith(mount) and len(mount) > len(best[0]):
                best = (mount, kind, device)
    except OSError:
        pass
    return f"{best[1]} on {best[2]}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--views", type=int, default=3, choices=(1, 2, 3))
    parser.add_argument("--modes", default="off,1,0.1", help="comma-separated: off or fsync_s seconds")
    parser.add_argument("--repeat", type=int, default=1, help="run the modes this many times in turn")
    parser.add_argument("--dir", type=Path, default=None, help="where to record (default: the temporary folder)")
    parser.add_argument("--json", type=Path, default=None, help="also write the results here")
    args = parser.parse_args()
    modes = [None if m.strip() == "off" else float(m) for m in args.modes.split(",")]
    root = Path(tempfile.mkdtemp(prefix="recorder_fsync_", dir=args.dir))
    runs: list[list[dict]] = [[] for _ in modes]
    try:
        print(f"{args.seconds:g} s at 30 Hz × {args.repeat}, {args.views} view(s) 640×480 + every JSON stream, "
              f"into {root} ({filesystem_of(root)}), {os.cpu_count()} cores, {platform.machine()}, "
              f"load {os.getloadavg()[0]:.1f}")
        for _ in range(args.repeat):
            for n, fsync_s in enumerate(modes):
                runs[n].append(record(root / f"mode{n}", fsync_s, args.seconds, args.views))
                shutil.rmtree(root / f"mode{n}")
        print(f"{'fsync':<14}{'frames':>7}{'dropped':>8}{'write p50':>11}{'p99':>9}{'max':>9}{'total':>9}"
              f"{'rounds':>8}{'round p50':>11}{'p99':>9}{'sync total':>12}{'stop':>8}{'MB':>7}")
        results = [summary(fsync_s, runs[n]) for n, fsync_s in enumerate(modes)]
        for row in results:
            w, s = row["per_write"], row["sync_rounds"]
            print(f"{row['fsync']:<14}{row['frames']:>7}{row['dropped']:>8}{w['p50_ms']:>9.1f}ms{w['p99_ms']:>7.1f}ms"
                  f"{w['max_ms']:>7.1f}ms{w['total_s']:>8.2f}s{s['count']:>8}"
                  + (f"{s['p50_ms']:>9.1f}ms{s['p99_ms']:>7.1f}ms{s['total_s']:>11.3f}s" if s["count"] else
                     f"{'-':>11}{'-':>9}{'-':>12}")
                  + f"{row['stop_s']:>7.2f}s{row['mb']:>7.1f}", flush=True)
        print(f"load after: {os.getloadavg()[0]:.1f}")
    finally:
        shutil.rmtree(root, ignore_errors=True)
    if args.json:
        args.json.write_text(json.dumps({"seconds": args.seconds, "views": args.views, "repeat": args.repeat,
                                         "results": results}, indent=1))


if __name__ == "__main__":
    main()
