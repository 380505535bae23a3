"""What the Rerun recording and the 3D hand panel cost per frame, on the bundled sample episode (300 frames):
the 3D panel (`viz.hand3d_panel`, four hand views) per frame; logging one replayed frame (its observation and
its prediction, the measured map standing in for the prediction) with the episode's MP4s as video assets, and
with every camera frame as JPEG (HDF5 episodes, the live rig at half size); the file's size per minute of
episode. Times are the calling thread's CPU time (robust on a busy machine) and the wall time.

    python benchmarks/rerun_costs.py [--json docs/bench/rerun_costs.json] [--md docs/bench/rerun_costs.md]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from report_files import add_report_arguments, machine, write_report  # benchmarks/ is the script's folder

ROOT = Path(__file__).resolve().parents[1]
EPISODE = ROOT / "recordings" / "sample" / "Home" / "slide_box_cardboard" / "sim0007_00000"


def _timed(step, frames: int) -> dict:
    cpu, wall = time.thread_time(), time.perf_counter()
    for i in range(frames):
        step(i)
    return {"cpu_ms": 1e3 * (time.thread_time() - cpu) / frames, "wall_ms": 1e3 * (time.perf_counter() - wall) / frames}


def panel_cost(episode) -> dict:
    from touchanything.viz.hand3d_panel import hand3d_panel

    grids, hands = episode.pressure.grids, episode.wilor
    return _timed(lambda i: hand3d_panel(hands.joints[i].reshape(42, 3), hands.valid[i], grids[i], grids[i]), episode.num_frames)


def logging_cost(episode, folder: Path, videos: bool, scale: float) -> dict:
    """Log every frame of the episode; the cost per frame and the file's MB per minute of episode."""
    from touchanything.app.sessions.replay_export import log_episode_videos
    from touchanything.core.snapshot import VIEW_NAMES
    from touchanything.core.tactile_layout import TactileLayout
    from touchanything.inference.evaluation.running_metrics import RunningMetrics
    from touchanything.viz.frame_facts import frame_facts
    from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

    bend, grids, hands = TactileLayout.default().bend, episode.pressure.grids, episode.wilor
    images = [{v: s.read(i) for v, s in episode.views.items()} for i in range(episode.num_frames)]  # decoded beforehand
    path = folder / f"cost_{videos}_{scale}.rrd"
    recording = RerunRecording(RerunTarget(path, image_scale=scale), "cost", {"benchmark": "rerun_costs"})
    metrics = RunningMetrics(bend)
    facts = []  # decided beforehand, as the session does before it hands a frame to the logger
    for i in range(episode.num_frames):
        metrics.add(grids[i], grids[i])
        facts.append(frame_facts(grids[i], hands.valid[i], grids[i], bend, metrics=metrics))
    if videos:
        log_episode_videos(recording, episode, VIEW_NAMES)

    def step(i: int) -> None:
        t, joints, valid = i / 30, hands.joints[i].reshape(42, 3), hands.valid[i]
        recording.log_observation(i, t, images[i], joints, valid, grids[i], facts[i], {})
        recording.log_prediction(i, t, grids[i], facts[i], joints, valid, grids[i], 12.0, 11.0)

    row = _timed(step, episode.num_frames)
    recording.close()
    return row | {"mb_per_minute": path.stat().st_size / 1e6 * 60 / (episode.num_frames / episode.fps)}


def markdown(record: dict) -> str:
    lines = ["# Rerun recording and 3D hand panel: cost per frame (bundled sample, 300 frames)", "",
             f"{record['machine']}; load average at the start {record['load']}; `{record['command']}`.", "",
             "| what | CPU ms per frame | wall ms per frame | file MB per minute |", "|---|---|---|---|",
             f"| 3D hand panel (4 views) | {record['panel']['cpu_ms']:.1f} | {record['panel']['wall_ms']:.1f} | – |"]
    for key, label in (("videos", "logging a replayed frame, cameras as the episode's MP4 (video assets)"),
                       ("jpeg", "logging a replayed frame, cameras as JPEG (HDF5 episodes)"),
                       ("live", "logging a live frame, cameras as JPEG at half size")):
        r = record[key]
        lines.append(f"| {label} | {r['cpu_ms']:.1f} | {r['wall_ms']:.1f} | {r['mb_per_minute']:.0f} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    from touchanything.devices.episodes.episode_loader import open_episode

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_report_arguments(parser)
    args = parser.parse_args()
    record = {"machine": machine(),
              "load": " ".join(f"{x:.1f}" for x in os.getloadavg()),
              "command": "python benchmarks/rerun_costs.py " + " ".join(sys.argv[1:])}
    with open_episode(EPISODE) as episode, tempfile.TemporaryDirectory() as folder:
        record["panel"] = panel_cost(episode)
        record["videos"] = logging_cost(episode, Path(folder), True, 1.0)
        record["jpeg"] = logging_cost(episode, Path(folder), False, 1.0)
        record["live"] = logging_cost(episode, Path(folder), False, 0.5)
    write_report(record, markdown(record), args.json, args.md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
