"""`touchanything live --scene FILE`: the live rig of a scene (the capture rig, the simulated rig, or a webcam
with the hands estimated from it) through the engine into the dashboard, or with `--headless` for a fixed time
with a status line per second (no display needed)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from touchanything.app.sessions.scene import Scene

from touchanything.app.sessions.engine_choice import add_device_argument, add_onnx_argument
from touchanything.app.sessions.rerun_output import (
    LIVE_IMAGE_SCALE,
    add_rerun_arguments,
    finish,
    open_recording,
    rerun_target,
    session_properties,
)
from touchanything.app.sessions.setting_choice import PickedSetting, add_setting_arguments, picked_setting, setting_request
from touchanything.core.errors import require_finite_positive
from touchanything.core.output_safety import add_overwrite_argument

SHOWN_METRICS = ("temporal_accuracy", "contact_iou", "volumetric_iou", "mae")


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("live", help="the live rig of a scene (devices or the simulated rig) in the dashboard")
    parser.add_argument("--scene", type=Path, required=True, help="scene file (TOML), e.g. scenes/sim.toml")
    parser.add_argument("--headless", action="store_true", help="no window: run for --seconds and print status")
    parser.add_argument("--seconds", type=float, default=10.0, help="how long --headless runs (default 10)")
    add_onnx_argument(parser)
    add_setting_arguments(parser)
    add_device_argument(parser, default=None)
    add_rerun_arguments(parser)
    add_overwrite_argument(parser, "--rerun")
    parser.set_defaults(run=run)


def open_live_session(scene: Scene | Path, device: str | None = None, picked: PickedSetting | None = None,
                      onnx: Path | None = None):
    """The scene's (a Scene, or a scene file to read) rig and model as a LiveSession (not started), the model on
    `device` when given (else the scene's), the `picked` setting's model, tier and views, or the `onnx` export
    (`export_choice`), instead of the scene's when given; a model that fails to load leaves the session without predictions, with the reason
    in its message (a folder that is no export is a UserError)."""
    from touchanything.app.sessions.engine_choice import build_engine, export_choice
    from touchanything.app.sessions.live_session import LiveSession
    from touchanything.app.sessions.scene import Scene, read_scene
    from touchanything.app.sessions.scene_rig import LiveRig
    from touchanything.core.errors import UserError
    from touchanything.core.snapshot import VIEW_NAMES

    scene = scene if isinstance(scene, Scene) else read_scene(scene)
    choice = scene.model if device is None else scene.model.with_setting(device=device)
    if picked is not None:
        choice = picked.model_choice(choice.setting.device)
    elif onnx is not None:
        choice = export_choice(onnx, choice.setting.device)
    try:
        engine, message = build_engine(choice.with_setting(views=VIEW_NAMES)), ""
    except UserError as exc:
        engine, message = None, f"no prediction: {exc}"
        print(message)
    session = LiveSession(LiveRig(scene), engine, choice, message)
    session.set_views(choice.setting.views)
    session.budget = picked and picked.budget_watch()
    return session


def run_headless(session, seconds: float) -> dict:
    """Run the started session for `seconds`, printing one status line per second; returns a summary."""
    from touchanything.core.view_sets import VIEW_LABELS
    from touchanything.viz.frame_facts import metric_text
    from touchanything.viz.hand_projection import pose_label

    deadline, over = time.monotonic() + seconds, ""
    while time.monotonic() < deadline:
        time.sleep(min(1.0, max(deadline - time.monotonic(), 0)))
        state = session.state()
        if session.budget is not None and session.budget.said != over:
            over = session.budget.said
            print(over, flush=True)
        prediction = state.prediction
        latency = "-" if prediction is None else f"{prediction.latency_ms:.0f} ms"
        print(f"{time.strftime('%H:%M:%S')}  rig {session.frames.rate():4.1f} Hz  engine {state.engine_fps:4.1f} fps  "
              f"latency {latency}  " + "  ".join(f"{VIEW_LABELS.get(row.name, row.name)}: {'ok' if row.connected else 'DOWN'}"
                                                     for row in state.sources)
              + f"  {pose_label(state.snapshot)}", flush=True)
    state = session.state()
    history = state.history.get("latency_ms", np.zeros(0))
    summary = {"snapshots": session.frames.count, "predictions": 0 if session.live is None else session.live.stats.processed,
               "dropped": 0 if session.live is None else session.live.stats.dropped,
               "latency_p50_ms": float(np.median(history)) if history.size else None, "cumulative": state.cumulative}
    engine = "" if session.live is None else f", {session.live.engine.runtime.capture}"
    print(f"model     {state.model}{engine}")
    print(f"summary   {summary['snapshots']} snapshots, {summary['predictions']} predictions, {summary['dropped']} "
          f"dropped by the engine; latency p50 {summary['latency_p50_ms'] or float('nan'):.0f} ms")
    if session.budget is not None and (line := session.budget.after(state.step_p99_ms)):
        print(line)
    if state.cumulative is not None:
        print("metrics   " + ", ".join(f"{k} {metric_text(v)}" for k, v in state.cumulative.items() if k in SHOWN_METRICS)
              + " (against the gloves' live pressure)")
    return summary


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.rerun_sink import RerunSink, seconds_since_first
    from touchanything.app.sessions.scene import read_scene
    from touchanything.viz.dashboard.dashboard import Dashboard
    from touchanything.viz.display import display_problem

    if args.headless:
        require_finite_positive("--seconds", args.seconds)
    if not args.headless and (problem := display_problem()):
        from touchanything.core.errors import UserError

        raise UserError(f"cannot open the dashboard: {problem}; use --headless")
    request = setting_request(args)
    target = rerun_target(args, (args.scene, args.onnx, *(request.inputs if request else ())), LIVE_IMAGE_SCALE)
    scene = read_scene(args.scene)
    print(f"starting  the rig of {args.scene} and loading the model (devices connect, the model loads: seconds)…",
          flush=True)
    session = open_live_session(scene, args.device, picked_setting(request, args.device), args.onnx)
    session.use_atlas(args.atlas)
    engine = session.live and session.live.engine
    recording = target and open_recording(target, f"live {args.scene.stem}", session_properties(session.choice, engine))
    if recording is not None:
        session.rerun = RerunSink(recording, session.bend, seconds_since_first())
    try:
        session.start()
        if args.headless:
            try:
                run_headless(session, args.seconds)
            finally:
                session.close()
        else:
            stats = Dashboard(session).run()
            print(f"dashboard closed after {stats.frames} frames ({stats.fps:.0f} fps)")
    finally:
        if recording is not None:
            print(session.rerun.line())
            finish(recording, keep_serving=args.headless)
    return 0
