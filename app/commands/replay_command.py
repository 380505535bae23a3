"""`touchanything replay PATH`: an episode (or any plain video, with the hands estimated from its frames)
through the streaming engine in the dashboard, or with `--headless` exported as a comparison video (cameras;
ground truth, prediction, error) with running metrics and latency."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.app.sessions.bundled import OUTPUT_DIR
from touchanything.app.sessions.engine_choice import (
    ModelChoice,
    add_device_argument,
    add_onnx_argument,
    choice_inputs,
    choose,
    default_checkpoint,
    export_choice,
    view_set_argument,
)
from touchanything.app.sessions.rerun_output import add_rerun_arguments, rerun_target
from touchanything.app.sessions.setting_choice import add_setting_arguments, picked_setting, setting_request
from touchanything.core.output_safety import add_overwrite_argument
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.view_sets import VIEW_HELP
from touchanything.inference.engine.engine_setting import RUNTIMES
from touchanything.viz.display import display_problem


def add_engine_arguments(parser: argparse.ArgumentParser) -> None:
    """The model, runtime, views and device options, `--onnx`, and `--setting` (which decides all but the device)."""
    parser.add_argument("--checkpoint", type=Path, help="model checkpoint (default: the bundled pico model; with --onnx "
                                                        "the checkpoint the export was made from)")
    parser.add_argument("--config", type=Path, help="config.yaml (default: beside the checkpoint)")
    parser.add_argument("--views", nargs="+", type=view_set_argument, metavar="VIEWS",
                        help=f"views the model uses, one or more ({VIEW_HELP}; ego is required for a prediction; "
                             "default all)")
    parser.add_argument("--runtime", choices=list(RUNTIMES),
                        help="torch, or onnx (ONNX Runtime on the CPU; the model is exported on first use into the user "
                             "cache; default torch)")
    parser.add_argument("--precision", help="torch: fp32, bf16 (fp16, tf32 on a GPU); onnx: fp32, int8 (default fp32)")
    add_onnx_argument(parser)
    add_setting_arguments(parser)
    add_device_argument(parser)


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("replay", help="replay an episode or a plain video through the engine in the dashboard, "
                                                "or into a video")
    parser.add_argument("episode", type=Path, help="raw episode folder, .hdf5 trajectory, or any video file (an ego-only "
                                                   "episode: the hands are estimated from its frames)")
    add_engine_arguments(parser)
    parser.add_argument("--headless", action="store_true", help="no window: write the comparison video instead")
    parser.add_argument("--out", type=Path, help="the comparison video to write (.mp4; implies --headless; "
                                                  f"default {OUTPUT_DIR}/<trajectory>_replay.mp4 in the working directory)")
    parser.add_argument("--hand3d", action="store_true", help="add the pressure painted on 3D hands (measured | "
                                                              "predicted) to the comparison video (default: off)")
    add_rerun_arguments(parser)
    add_overwrite_argument(parser, "--out (a file other than an earlier comparison video) or --rerun")
    parser.set_defaults(run=run)


def given_choice(args: argparse.Namespace) -> ModelChoice:
    """The options' model and setting: the `--onnx` export, else the checkpoint (the bundled pico, torch fp32 by
    default), with the union of the `--views` values (default all)."""
    views = tuple(v for v in VIEW_NAMES if any(v in chosen for chosen in args.views or [VIEW_NAMES]))
    if args.onnx is not None:
        return export_choice(args.onnx, args.device, args.checkpoint, args.config, args.runtime, args.precision,
                             views=views)
    return choose(args.checkpoint or default_checkpoint(), args.config, runtime=args.runtime or "torch",
                  precision=args.precision or "fp32", device=args.device, views=views)


def default_video(path: Path) -> Path:
    """recordings/<trajectory folder, or file name without its suffix>_replay.mp4"""
    name = path.resolve().name
    return OUTPUT_DIR / f"{Path(name).stem if path.is_file() else name}_replay.mp4"


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.replay_inputs import check_episodes, check_video_output

    check_episodes([args.episode])  # before anything loads torch: a bad path is one line at once
    request = setting_request(args)
    given = None if request else given_choice(args)
    inputs = (args.episode, *(request.inputs if request else choice_inputs(given)))
    rerun = rerun_target(args, inputs)
    headless = args.headless or args.out is not None
    out = args.out or default_video(args.episode)
    if headless:
        check_video_output(out, inputs, args.overwrite)
    picked = picked_setting(request, args.device)
    choice = picked.model_choice(args.device) if picked else given
    from touchanything.app.sessions.replay_runs import replay_in_dashboard, replay_to_video  # loads torch

    if not headless and rerun is not None and (problem := display_problem()):
        print(f"no dashboard: {problem}. Writing the Rerun recording only (--headless: the comparison video too).")
        replay_to_video([args.episode], choice, None, rerun=rerun, budget=picked and picked.budget_watch())
    elif headless:
        replay_to_video([args.episode], choice, out, args.hand3d, rerun, picked and picked.budget_watch())
    else:
        stats = replay_in_dashboard(args.episode, choice, rerun=rerun, atlas=args.atlas,
                                    budget=picked and picked.budget_watch()).stats
        print(f"dashboard closed after {stats.frames} frames ({stats.fps:.0f} fps)")
    return 0
