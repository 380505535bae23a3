"""The `--rerun FILE.rrd` and `--rerun-serve [PORT]` options of demo, replay, live and eval: the output checked
before any work, the recording opened, a served recording kept up until Ctrl-C, and several recordings
(eval: one per trajectory) merged into one file."""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.app.sessions.engine_choice import ModelChoice, model_label
from touchanything.core.errors import UserError
from touchanything.core.output_safety import check_output, replacing

if TYPE_CHECKING:  # rerun, torch and the episode readers are imported where used: --help loads this module
    from touchanything.devices.episodes.episode import Episode
    from touchanything.inference.engine.streaming_engine import StreamingEngine
    from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

DEFAULT_WEB_PORT = 9090
LIVE_IMAGE_SCALE = 0.5
"""The live rig's camera frames go into a recording at half their size (JPEG): a quarter of the bytes and of
the encoding time, which the live path's CPU needs more (docs/rerun.md, "Costs")."""


def add_rerun_arguments(parser: argparse.ArgumentParser, serve: bool = True) -> None:
    """--rerun and (`serve`) --rerun-serve (the command adds the one `--overwrite`, see output_safety)."""
    parser.add_argument("--rerun", type=Path, metavar="FILE.rrd",
                        help="also write a Rerun recording of the session (cameras, 3D hands with the pressure painted on "
                             "them, measured and predicted maps, contact, official metrics, latency, trackers); open it "
                             "with `rerun FILE.rrd` (default: none)")
    if serve:
        parser.add_argument("--rerun-serve", type=int, nargs="?", const=DEFAULT_WEB_PORT, metavar="PORT",
                            help=f"also serve the recording to a web viewer at http://localhost:PORT (default port "
                                 f"{DEFAULT_WEB_PORT}; default: not served), on this machine only unless --rerun-serve-host")
        parser.add_argument("--rerun-serve-host", metavar="ADDRESS", default=None,
                            help="with --rerun-serve: serve the data on this address of the machine (e.g. its LAN address, "
                                 "or 0.0.0.0 for every interface) to watch from another machine; unauthenticated "
                                 "(default: 127.0.0.1, this machine only)")


def check_rrd_output(path: Path, overwrite: bool, inputs: Iterable[Path | None] = ()) -> None:
    """Before any work: `path` ends in .rrd and passes the output rule (output_safety.check_output) against
    the command's `inputs`. UserError (one line) otherwise."""
    if path.suffix.lower() != ".rrd":
        raise UserError(f"{path}: a Rerun recording must be an .rrd file")
    check_output(path, inputs, overwrite)


def rerun_target(args: argparse.Namespace, inputs: Iterable[Path | None] = (), image_scale: float = 1.0) -> RerunTarget | None:
    """The target of the command's --rerun / --rerun-serve options (None: neither), checked against the
    command's `inputs`."""
    host = getattr(args, "rerun_serve_host", None)
    if host is not None and args.rerun_serve is None:
        raise UserError("--rerun-serve-host: only with --rerun-serve (it says where the served recording is watched)")
    if args.rerun is None and args.rerun_serve is None:
        return None
    if args.rerun is not None:
        check_rrd_output(args.rerun, args.overwrite, inputs)
    if args.rerun_serve is not None and not 0 < args.rerun_serve < 65536:
        raise UserError(f"--rerun-serve: {args.rerun_serve} is not a port number (1–65535)")
    from touchanything.viz.rerun_recording import RerunTarget
    from touchanything.viz.rerun_serving import LOCALHOST, check_serve_host

    try:
        host = LOCALHOST if host is None else check_serve_host(host)
    except ValueError as exc:
        raise UserError(str(exc)) from None

    return RerunTarget(args.rerun, args.rerun_serve, image_scale=image_scale, serve_host=host)


def open_recording(target: RerunTarget, name: str, properties: Mapping[str, str]) -> RerunRecording:
    """Open the recording; says where it is served. A port already in use is a UserError."""
    from touchanything.viz.rerun_recording import RerunRecording

    try:
        recording = RerunRecording(target, name, properties)
    except (OSError, RuntimeError, ValueError) as exc:
        raise UserError(f"cannot start the Rerun recording: {exc}") from None
    if recording.served is not None:
        print("\n".join(recording.served.lines()), flush=True)
    return recording


def finish(recording: RerunRecording, keep_serving: bool = True) -> None:
    """Close the recording (the file is renamed into place) and say where it is; a served recording first sends
    every row held back and says how many the data server holds and what it dropped (`ServedHistory.line`); with
    `keep_serving`, it then stays up until Ctrl-C (a headless run: a viewer can still look at all of it)."""
    if recording.url:
        recording.flush()
        print(recording.history.line(), flush=True)
    if recording.url and keep_serving:
        print(f"rerun     still serving at {recording.url}; Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            print("rerun     stopped serving")
    recording.close()
    if recording.target.rrd is not None:
        print(f"rerun     {recording.target.rrd} (open with: rerun {recording.target.rrd})")


def episode_name(episode: Episode) -> str:
    """"Scene/task/trajectory", or the file name of a plain video."""
    from touchanything.devices.episodes.episode_loader import is_plain_video

    return episode.path.name if is_plain_video(episode) else f"{episode.scene}/{episode.task}/{episode.trajectory_id}"


def session_properties(choice: ModelChoice, engine: StreamingEngine | None, episode: Episode | None = None) -> dict[str, str]:
    """What a recording says about itself: the model, the engine setting and, for a replay, the episode."""
    properties = {"model": model_label(choice, engine) if engine is not None else "no model"}
    properties |= {"setting": choice.setting.name()} if engine is not None else {}
    if episode is not None:
        properties |= {"episode": str(episode.path), "frames": str(episode.num_frames), "fps": f"{episode.fps:g}"}
    return properties


def merge_recordings(parts: list[Path], out: Path) -> None:
    """Merge .rrd files (each its own recording) into `out` with Rerun's own `rrd merge` (written under a
    temporary name and renamed, output_safety.replacing); the parts are removed."""
    with replacing(out) as temporary:
        command = [sys.executable, "-m", "rerun_cli", "rrd", "merge", *map(str, parts), "-o", str(temporary)]
        result = subprocess.run(command, capture_output=True, text=True, env={**os.environ, "RUST_LOG": "warn"})
        if result.returncode != 0:
            raise UserError(f"{out}: merging the recordings failed ({result.stderr.strip().splitlines()[-1:]})")
    for part in parts:
        part.unlink(missing_ok=True)
