"""Dashboard frame rate, display lag and CPU share under Xvfb: the bundled sample replayed at 30 fps through
the engine and the dashboard, and the simulated live rig (scenes/sim.toml: its simulator runs on the same
cores), one fresh process per run (dearpygui allows one dashboard per process).

    python benchmarks/dashboard_fps.py [--frames 200] [--rounds 3] [--out docs/bench] [--before FILE] [--cpu-only]
        [--checkpoint CKPT] [--tiers torch-fp32 onnx-int8]

The CPU rows replay the sample with the default model (pico), on each of `--tiers`, and measure, over a fixed
window: the dashboard process's CPU (all its threads, and split into engine, player, display and software
OpenGL) and the X server's, paused and playing, and the engine's predictions/s and capture-to-prediction latency while a second CPU-bound
process runs beside it. `--before` takes an earlier dashboard.json and puts its CPU rows beside these.

The settings are interleaved round by round (this machine's speed drifts), one row per run.

Starts its own Xvfb when no display is reachable. Writes dashboard.md and dashboard.json.
"""
from __future__ import annotations

import argparse
import itertools
import json
import multiprocessing
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

SETTINGS = (("no model", None), ("pico torch-fp32", "torch-fp32"), ("pico onnx-int8", "onnx-int8"),
            ("live sim rig, pico torch-fp32", "live"))
LIVE_SCENE = Path("scenes/sim.toml")
CPU_SETTINGS = ("paused", "playing", "playing beside a CPU-bound process")
CPU_TIERS = ("torch-fp32", "onnx-int8")
WINDOW_S = 5.0
"""Each CPU row measures over this window (within the 10 s sample: playing rows restart it at frame 0)."""


def measure(tier: str | None, frames: int) -> dict:
    from touchanything.app.commands.live_command import open_live_session
    from touchanything.app.sessions.bundled import sample_episodes
    from touchanything.app.sessions.engine_choice import build_engine, choose, default_checkpoint
    from touchanything.app.sessions.replay_session import ReplaySession
    from touchanything.devices.episodes.episode_loader import open_episode
    from touchanything.viz.dashboard.dashboard import Dashboard

    if tier == "live":
        session = open_live_session(LIVE_SCENE).start()
        stats = Dashboard(session).run(max_frames=frames)
        engine_fps = session.state().engine_fps
    else:
        choice = choose(default_checkpoint()).with_tier(tier or "torch-fp32")
        with open_episode(sample_episodes()[0]) as episode:
            engine = build_engine(choice) if tier else None
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


def measure_cpu(setting: str, x_server: int | None, checkpoint: Path | None, tier: str) -> dict:
    """One CPU row: the sample with `checkpoint` (None: the default pico) on `tier` in the dashboard, driven from a
    thread (paused, or playing from frame 0) and measured over WINDOW_S once the first prediction is on screen."""
    import threading

    from touchanything.app.sessions.bundled import sample_episodes
    from touchanything.app.sessions.engine_choice import build_engine, choose, default_checkpoint
    from touchanything.app.sessions.replay_session import ReplaySession
    from touchanything.devices.episodes.episode_loader import open_episode
    from touchanything.viz.dashboard.dashboard import Dashboard

    choice = choose(checkpoint or default_checkpoint()).with_tier(tier)
    result: dict = {}
    with open_episode(sample_episodes()[0]) as episode:
        session = ReplaySession(episode, build_engine(choice), choice).start()
        dashboard = Dashboard(session)

        def drive() -> None:
            try:
                while session.state().prediction is None:
                    time.sleep(0.05)
                if setting == "paused":
                    session.pause()
                else:
                    session.seek(0)
                time.sleep(1.0)
                frames, processed = dashboard.stats.frames, session.live.stats.processed
                wall, cpu, x_cpu = time.monotonic(), time.process_time(), process_cpu_s(x_server)
                threads = thread_cpu_s()
                time.sleep(WINDOW_S)
                seconds = time.monotonic() - wall
                parts = thread_groups(threads, thread_cpu_s(), seconds)
                latency = session.state().history["latency_ms"]
                predictions = session.live.stats.processed - processed
                result.update(
                    cpu_percent=100 * (time.process_time() - cpu) / seconds,
                    x_cpu_percent=None if x_server is None else 100 * (process_cpu_s(x_server) - x_cpu) / seconds,
                    display_fps=(dashboard.stats.frames - frames) / seconds,
                    predictions_per_s=predictions / seconds,
                    latency_p50_ms=float(np.median(latency[-predictions:])) if predictions else None,
                    load=os.getloadavg()[0], **parts)
            finally:
                dashboard.close()

        thread = threading.Thread(target=drive, daemon=True)
        thread.start()
        dashboard.run()
        thread.join(5)
    return result


THREAD_GROUPS = (("engine_cpu_percent", "engine"), ("player_cpu_percent", "replay", "av:"),
                 ("display_cpu_percent", "MainThread"), ("rasterizer_cpu_percent", "llvmpipe"))
"""Where the process's CPU goes: (row key, name prefixes of its threads). A Python thread is named by `threading`
(the engine's and the player's threads carry "engine" / "replay" in their names), a native one by the OS (PyAV's
decoder threads "av:…", Mesa's software rasterizer "llvmpipe-N"); the rest is `other_cpu_percent`."""


def thread_cpu_s() -> dict[int, tuple[str, float]]:
    """This process's threads: OS thread id → (name, CPU seconds so far); a Python thread's name is its
    `threading` name, a native thread's the OS's."""
    import threading

    names = {t.native_id: t.name for t in threading.enumerate()}
    found = {}
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/stat") as stat:
                text = stat.read()
        except OSError:
            continue
        fields = text.rpartition(")")[2].split()
        name = names.get(int(task), text[text.index("(") + 1:text.rindex(")")])
        found[int(task)] = (name, (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK"))
    return found


def thread_groups(before: dict, after: dict, seconds: float) -> dict[str, float]:
    """% of a core each THREAD_GROUPS group (and `other_cpu_percent`) used between two thread_cpu_s() readings."""
    shares = dict.fromkeys([key for key, *_ in THREAD_GROUPS] + ["other_cpu_percent"], 0.0)
    for tid, (name, cpu) in after.items():
        used = cpu - before.get(tid, (name, 0.0))[1]
        key = next((key for key, *prefixes in THREAD_GROUPS
                    if any(p in name if p in ("engine", "replay") else name.startswith(p) for p in prefixes)),
                   "other_cpu_percent")
        shares[key] += 100 * used / seconds
    return shares


def process_cpu_s(pid: int | None) -> float:
    """CPU seconds (user + system) used so far by process `pid` (0 for None)."""
    if pid is None:
        return 0.0
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rpartition(")")[2].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def busy() -> None:
    """The competing process: one core's worth of pure Python work until terminated."""
    while True:
        pass


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


def cpu_table(rows: list[dict], before: list[dict]) -> list[str]:
    """Medians per CPU setting, after (these rows) and, when given, before."""
    def cell(runs: list[dict], key: str, unit: str) -> str:
        values = [r[key] for r in runs if r.get(key) is not None]
        return "-" if not values else f"{np.median(values):.1f}{unit}"

    keys = (("cpu_percent", " %"), ("engine_cpu_percent", " %"), ("player_cpu_percent", " %"),
            ("display_cpu_percent", " %"), ("rasterizer_cpu_percent", " %"), ("x_cpu_percent", " %"),
            ("display_fps", ""), ("predictions_per_s", ""), ("latency_p50_ms", " ms"), ("load", ""))
    titles = ("dashboard process CPU (% of a core)", "of which engine", "player and decoders", "display (main thread)",
              "software OpenGL", "X server CPU", "display fps", "engine predictions/s", "latency p50",
              "load average (1 min)")
    lines = [f"| setting | {' | '.join(titles)} |", "|---|" + "---|" * len(titles)]
    for label, runs in (("before", before), ("after", rows)) if before else (("", rows),):
        for setting, tier in itertools.product(CPU_SETTINGS, dict.fromkeys(r.get("tier", "torch-fp32") for r in runs)):
            chosen = [r for r in runs if r["setting"] == setting and r.get("tier", "torch-fp32") == tier]
            if chosen:
                name = f"{setting}, pico {tier}" + (f", {label}" if label else "")
                lines.append(f"| {name} | " + " | ".join(cell(chosen, key, unit) for key, unit in keys) + " |")
    return lines


def markdown(rows: list[dict], before: list[dict]) -> str:
    cpu_rows = [r for r in rows if r["setting"] in CPU_SETTINGS]
    rows = [r for r in rows if r["setting"] not in CPU_SETTINGS]
    lines = ["# Dashboard frame rate and CPU share (Xvfb, llvmpipe, 2-core CPU)", "",
             "## CPU share", "",
             f"The bundled sample with the pico model in the dashboard (torch-fp32: the dashboard's default runtime; "
             f"onnx-int8: the atlas's fastest); medians of the runs, each measured over {WINDOW_S:g} s. Paused: the "
             "replay paused after its first prediction. Playing: from frame 0. Beside a CPU-bound process: a second "
             "process spinning in pure Python for the whole run. The process's CPU is split by thread: the engine, the "
             "player with its video decoders, the display's main thread (building the panels, dearpygui), and "
             "software OpenGL (Mesa's llvmpipe rasterizer threads, which the dashboard runs at nice 12, below the "
             "engine's 8: viz/dashboard/render_priority.py). The load average is the machine's.", "",
             *cpu_table(cpu_rows, [r for r in before if r["setting"] in CPU_SETTINGS]), "",
             "## Frame rate", "",
             "The bundled sample replayed at 30 fps through the engine into the dashboard (1280×720, everything "
             "shown); `python benchmarks/dashboard_fps.py`.", "",
             "| setting | display fps min / median / max | runs at ≥ 30 fps (the target) |", "|---|---|---|"]
    for setting in dict.fromkeys(r["setting"] for r in rows):
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
    parser.add_argument("--before", type=Path, help="an earlier dashboard.json whose CPU rows are shown beside these")
    parser.add_argument("--cpu-only", action="store_true", help="only the CPU rows (quicker)")
    parser.add_argument("--checkpoint", type=Path, help="the model of the CPU rows (default: the bundled pico)")
    parser.add_argument("--tiers", nargs="+", default=list(CPU_TIERS), help="the runtimes and precisions of the CPU "
                        "rows (default: torch-fp32, the dashboard's, and onnx-int8, the atlas's fastest)")
    args = parser.parse_args()
    before = json.loads(args.before.read_text())["rows"] if args.before else []
    server = ensure_display()
    context = multiprocessing.get_context("spawn")
    try:
        rows = []
        for round_number in range(1, args.rounds + 1):
            for name, tier in () if args.cpu_only else SETTINGS:
                ticks = cpu_ticks()
                with context.Pool(1) as pool:
                    result = pool.apply(measure, (tier, args.frames))
                rows.append({"setting": name, "round": round_number, **result,
                             "steal_percent": steal_percent(ticks, cpu_ticks())})
                print(f"{name}, round {round_number}: {rows[-1]['fps']:.1f} fps", flush=True)
            for name, tier in itertools.product(CPU_SETTINGS, args.tiers):
                competitor = context.Process(target=busy, daemon=True) if "CPU-bound" in name else None
                if competitor is not None:
                    competitor.start()
                try:
                    with context.Pool(1) as pool:
                        result = pool.apply(measure_cpu, (name, server and server.pid, args.checkpoint, tier))
                finally:
                    if competitor is not None:
                        competitor.terminate()
                rows.append({"setting": name, "round": round_number, "tier": tier, **result})
                print(f"{name}, round {round_number}: {result}", flush=True)
    finally:
        if server is not None:
            server.terminate()
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "dashboard.json").write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    (args.out / "dashboard.md").write_text(markdown(rows, before))
    print(markdown(rows, before))


if __name__ == "__main__":
    main()
