"""`touchanything demo [EPISODE]`: the bundled sample's episodes through the bundled model in the dashboard, one
after the other (`TOUR`: where the model is right, then where it misses), over and over until the window is
closed; with no display, one pass of each into one comparison video (cameras; measured, predicted and error
maps) with a summary per episode and overall instead. EPISODE (or `--rerun`) plays one episode."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.app.sessions.bundled import OUTPUT_DIR, SAMPLE_DIR, sample_episodes
from touchanything.app.sessions.engine_choice import (
    add_device_argument,
    add_onnx_argument,
    choice_inputs,
    choose,
    default_checkpoint,
    export_choice,
)
from touchanything.app.sessions.rerun_output import add_rerun_arguments, rerun_target
from touchanything.app.sessions.setting_choice import add_setting_arguments, picked_setting, setting_request
from touchanything.core.errors import UserError
from touchanything.core.output_safety import add_overwrite_argument
from touchanything.viz.display import display_problem

DEMO_VIDEO = OUTPUT_DIR / "demo.mp4"


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("demo", help="the bundled sample's episodes in turn through the bundled model in the "
                                              "dashboard, looped until the window is closed")
    parser.add_argument("episode", type=Path, nargs="?",
                        help="raw episode folder, .hdf5 trajectory, or any video file (hands estimated from its frames; "
                             "default: the bundled sample's three episodes in turn)")
    parser.add_argument("--headless", action="store_true", help="write the comparison video instead of a window")
    parser.add_argument("--out", type=Path, default=DEMO_VIDEO,
                        help=f"video for --headless (default {DEMO_VIDEO} in the working directory)")
    parser.add_argument("--hand3d", action="store_true", help="add the pressure painted on 3D hands (measured | "
                                                              "predicted) to the comparison video (default: off)")
    add_onnx_argument(parser)
    add_setting_arguments(parser)
    add_device_argument(parser)
    add_rerun_arguments(parser)
    add_overwrite_argument(parser, "--out (a file other than an earlier comparison video) or --rerun")
    parser.set_defaults(run=run)


TOUR = ("Workbench", "Office", "Home")
"""The order in which the demo tours the bundled sample's scenes: where the model is right first (Workbench:
V-IoU 0.76, C-IoU 0.84 with pico), then where it misses (Home: 0.13 / 0.26); other scenes after, by name."""


def tour_order(paths: list[Path]) -> list[Path]:
    """The sample episodes in `TOUR` order (an episode's scene is the folder two above it)."""
    return sorted(paths, key=lambda p: (TOUR.index(p.parents[1].name) if p.parents[1].name in TOUR else len(TOUR), str(p)))


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.replay_inputs import check_episodes, check_video_output

    paths = [args.episode] if args.episode is not None else tour_order(sample_episodes())
    if not paths:
        raise UserError(f"{SAMPLE_DIR}: no bundled sample episode found; pass an episode path")
    if len(paths) > 1 and (args.rerun or args.rerun_serve is not None):
        print(f"demo      a Rerun recording holds one episode: {paths[0]} only (without --rerun the demo tours all {len(paths)})")
        paths = paths[:1]
    check_episodes(paths)  # before anything loads torch: a bad path is one line at once
    request = setting_request(args)
    given = None if request else (export_choice(args.onnx, args.device) if args.onnx is not None
                                  else choose(default_checkpoint(), device=args.device))
    inputs = (*paths, *(request.inputs if request else choice_inputs(given)))
    rerun = rerun_target(args, inputs)
    problem = None if args.headless else display_problem()
    if problem:
        print(f"no dashboard: {problem}. Writing the comparison video instead.")
    if args.headless or problem:
        check_video_output(args.out, inputs, args.overwrite)
    picked = picked_setting(request, args.device)
    choice = picked.model_choice(args.device) if picked else given
    from touchanything.app.sessions.replay_runs import replay_in_dashboard, replay_to_video  # loads torch

    if args.headless or problem:
        replay_to_video(paths, choice, args.out, args.hand3d, rerun, picked and picked.budget_watch())
        print(f"watch it with any video player: {args.out}")
    else:
        stats = replay_in_dashboard(paths[0], choice, rerun=rerun, loop=True, atlas=args.atlas, tour=paths[1:],
                                    budget=picked and picked.budget_watch()).stats
        print(f"dashboard closed after {stats.frames} frames ({stats.fps:.0f} fps)")
    return 0
