"""Dashboard frame rate and display lag under Xvfb: the bundled sample replayed at 30 fps through the
engine and the dashboard, and the simulated live rig (scenes/sim.toml: its simulator runs on the same
cores), one fresh process per run (dearpygui allows one dashboard per process).

    python benchmarks/dashboard_fps.py [--frames 200] [--rounds 3] [--out docs/bench]

The settings are interleaved round by round (this machine's speed drifts), one row per run.

Starts its own Xvfb when no display is reachable. Writes dashboard.md and dashboard.json.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

SETTINGS = (("no model", None), ("nano torch fp32", "torch fp32"), ("nano onnx int8", "onnx int8"),
            ("live sim rig, nano torch fp32", "live"))
LIVE_SCENE = Path("scenes/sim.toml")


def measure(tier: str | None, frames: int) -> dict:
    from touchanything.app.commands.live_command import open_live_session
    from touchanything.app.sessions.bundled import sample_episodes
    from touchanything.app.sessions.engine_choice import ModelChoice, build_engine, default_checkpoint
    from touchanything.app.sessions.replay_session import ReplaySession
    from touchanything.devices.episodes.episode_loader import open_episode
    from touchanything.devices.snapshot import VIEW_NAMES
    from touchanything.viz.dashboard.dashboard import Dashboard

    if tier == "live":
        session = open_live_session(LIVE_SCENE).start()
        stats = Dashboard(session).run(max_frames=frames)
        engine_fps = session.state().engine_fps
    else:
        choice = ModelChoice(default_checkpoint()).with_tier(tier or "torch fp32")
        with open_episode(sample_episodes()[0]) as episode:
            engine = build_engine(choice, VIEW_NAMES) if tier else None
            session = ReplaySession(episode, engine, choice).start()
            stats = Dashboard(session).run(max_frames=frames)
            engine_fps = session.state().engine_fps
    camera, prediction = np.array(stats.camera_lag_ms), np.array(stats.prediction_lag_ms)
    return {"fps": stats.fps, "frames": stats.frames, "seconds": stats.seconds,
            "camera_updates_per_s": len(camera) / stats.seconds,
            "camera_lag_p50_ms": float(np.median(camera)), "camera_lag_p99_ms": float(np.percentile(camera, 99)),
            "prediction_lag_p50_ms": float(np.median(prediction)) if prediction.size else None,
            "prediction_lag_p99_ms": float(np.percentile(prediction, 99)) if prediction.size else None,
            "engine_fps": engine_fps}


def cpu_ticks() -> np.ndarray:
    """The machine's CPU time counters (/proc/stat: user nice system idle iowait irq softirq steal ...)."""
    with open("/proc/stat") as stat:
        return np.array(stat.readline().split()[1:], np.int64)


def steal_percent(before: np.ndarray, after: np.ndarray) -> float:
    """Share of the machine's CPU time taken by the host (steal) between two cpu_ticks() readings."""
    delta = after - before
    return float(100 * delta[7] / max(delta.sum(), 1))


def ensure_display() -> subprocess.Popen | None:
    from touchanything.viz.display import display_problem

    if display_problem() is None:
        return None
    if shutil.which("Xvfb") is None:
        raise SystemExit("no X display and no Xvfb (apt-get install xvfb xauth)")
    os.environ["DISPLAY"] = ":97"
    server = subprocess.Popen(["Xvfb", ":97", "-screen", "0", "1920x1080x24", "-nolisten", "tcp", "-noreset"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 15
    while display_problem() is not None and time.monotonic() < deadline:
        time.sleep(0.05)
    return server


def markdown(rows: list[dict]) -> str:
    lines = ["# Dashboard frame rate (Xvfb, llvmpipe, 2-core CPU)", "",
             "The bundled sample replayed at 30 fps through the engine into the dashboard (1280×720, everything "
             "shown); `python benchmarks/dashboard_fps.py`.", "",
             "| setting | display fps min / median / max | runs at ≥ 30 fps (the target) |", "|---|---|---|"]
    for setting, _ in SETTINGS:
        fps = np.array([r["fps"] for r in rows if r["setting"] == setting])
        lines.append(f"| {setting} | {fps.min():.1f} / {np.median(fps):.1f} / {fps.max():.1f} | "
                     f"{int((fps >= 30).sum())} of {fps.size} |")
    lines += ["", "Each run, in order (steal: the share of this virtual machine's CPU time the host took during the "
              "run, which is what makes runs differ):", "",
              "| setting | display fps | camera updates/s | camera lag p50 / p99 ms | prediction lag p50 / p99 ms | engine fps | steal |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        name = f"{r['setting']} (round {r['round']})"
        pred = "-" if r["prediction_lag_p50_ms"] is None else f"{r['prediction_lag_p50_ms']:.0f} / {r['prediction_lag_p99_ms']:.0f}"
        lines.append(f"| {name} | {r['fps']:.1f} | {r['camera_updates_per_s']:.1f} | {r['camera_lag_p50_ms']:.0f} / "
                     f"{r['camera_lag_p99_ms']:.0f} | {pred} | {r['engine_fps']:.1f} | {r['steal_percent']:.0f} % |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200, help="frames per setting (keep within the 10 s sample)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("docs/bench"))
    args = parser.parse_args()
    server = ensure_display()
    try:
        rows = []
        for round_number in range(1, args.rounds + 1):
            for name, tier in SETTINGS:
                before = cpu_ticks()
                with multiprocessing.get_context("spawn").Pool(1) as pool:
                    result = pool.apply(measure, (tier, args.frames))
                rows.append({"setting": name, "round": round_number, **result,
                             "steal_percent": steal_percent(before, cpu_ticks())})
                print(f"{name}, round {round_number}: {rows[-1]['fps']:.1f} fps", flush=True)
    finally:
        if server is not None:
            server.terminate()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "dashboard.json").write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    (args.out / "dashboard.md").write_text(markdown(rows))
    print(markdown(rows))


if __name__ == "__main__":
    main()
