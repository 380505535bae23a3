"""`touchanything record --scene FILE --out DIR [--seconds S]`: the live rig's 30 Hz snapshots written as a
raw EgoTouch episode folder (crash-safe: a killed recording replays up to its last second; the files are
fsync'ed every `[recording] fsync_s` of the scene, 1 s by default, so a power loss loses about that much)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from touchanything.core.errors import require_finite_positive


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("record", help="record the live rig of a scene as a raw EgoTouch episode")
    parser.add_argument("--scene", type=Path, required=True, help="scene file (TOML), e.g. scenes/sim.toml")
    parser.add_argument("--out", type=Path, required=True, help="the episode folder to create")
    parser.add_argument("--seconds", type=float, help="stop after this long (default: until Ctrl+C)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.scene import read_scene, scene_inputs
    from touchanything.app.sessions.scene_rig import LiveRig
    from touchanything.core.output_safety import check_output, check_outside
    from touchanything.devices.episodes.episode_writer import check_new_episode
    from touchanything.devices.rig.recorder import Recorder, RecorderConfig

    scene = read_scene(args.scene)
    check_outside(args.out, scene_inputs(scene))
    check_output(args.out, scene_inputs(scene), folder=True)
    check_new_episode(args.out)
    if args.seconds is not None:
        require_finite_positive("--seconds", args.seconds)
    recorder = Recorder(RecorderConfig(args.out, fsync_s=scene.recording.fsync_s))
    print(f"starting  the rig of {args.scene} (its devices connect: seconds)…", flush=True)
    rig = LiveRig(scene)
    clock = rig.start()
    try:
        recorder.start()
        clock.subscribe(recorder.write)
        print(f"recording to {args.out} (Ctrl+C stops)", flush=True)
        deadline = None if args.seconds is None else time.monotonic() + args.seconds
        try:
            while deadline is None or time.monotonic() < deadline:
                time.sleep(0.5 if deadline is None else min(0.5, max(deadline - time.monotonic(), 0)))
        except KeyboardInterrupt:
            pass
        clock.unsubscribe(recorder.write)
    finally:
        rig.stop()
        counters = recorder.stop() if recorder.is_recording else None
    if counters is not None:
        print(f"recorded  {counters.written} frames, {counters.dropped} dropped, to {args.out}")
    return 0
