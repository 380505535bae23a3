"""`touchanything eval`: the official evaluation protocol, per view configuration and per scene."""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from touchanything.app.sessions.bundled import BASELINES, MODELS_DIR, bundled_baselines
from touchanything.app.sessions.engine_choice import add_device_argument, view_set_argument
from touchanything.app.sessions.rerun_output import add_rerun_arguments, check_rrd_output
from touchanything.core.errors import UserError
from touchanything.core.output_safety import add_overwrite_argument, check_report_folder, write_text
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import VIEW_HELP, VIEW_SETS, view_set_name, views_used
from touchanything.devices.episodes.dataset_split import SPLIT_FILE, SPLIT_KEYS, read_split
from touchanything.inference.evaluation.evaluation_report import RESULT_FILES, markdown, results_json
from touchanything.inference.model.torch_device import (
    PRECISIONS,
    ProcessGroup,
    check_precision,
    device_label,
    join_process_group,
    resolve_device,
)

if TYPE_CHECKING:
    from touchanything.app.sessions.rerun_trajectories import TrajectoryRecordings
    from touchanything.inference.evaluation.evaluation import EvaluationResult
    from touchanything.inference.model.models import TactileModel


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("eval", help="evaluate a checkpoint with the official metric protocol")
    parser.add_argument("--checkpoint", type=Path, required=True,
                        help="model checkpoint in the official format (best_model.pth, last.pth, …)")
    parser.add_argument("--config", type=Path, help="config.yaml (default: beside the checkpoint)")
    parser.add_argument("--data", type=Path, required=True, help="HDF5 root holding split.json")
    parser.add_argument("--split", default="test_seen", choices=SPLIT_KEYS, help="which list of the split file "
                                                                                 "(default test_seen)")
    parser.add_argument("--split-file", type=Path, help="split file (default: DATA/split.json)")
    parser.add_argument("--views", nargs="+", default=[VIEW_SETS["all"]], type=view_set_argument, metavar="VIEWS",
                        help=f"one or more view configurations, each evaluated on its own: ego, ego+left, ego+right, "
                             f"all ({VIEW_HELP}; default all)")
    parser.add_argument("--num-traj", type=int, help="only the first N trajectories of the split (default: all)")
    parser.add_argument("--batch-size", type=int, default=16, help="clips per forward pass (default 16)")
    parser.add_argument("--ego-path", choices=("frames", "views"), default="frames",
                        help="ego-only through the official frames= path (default) or the multi-view encoder")
    add_device_argument(parser)
    parser.add_argument("--precision", default="fp32", choices=tuple(PRECISIONS),
                        help="autocast precision (the official script evaluates under fp16 on a GPU; default fp32)")
    parser.add_argument("--pose-only-baseline", nargs="?", const=True, type=Path, metavar="CHECKPOINT",
                        help="also evaluate each view configuration with every frame black (pose only): CHECKPOINT (e.g. one "
                             "trained with `train --blank-images`), else the model's bundled twin trained on black frames "
                             "(models/nano → models/nano_pose_only), else this checkpoint; reports the share of each "
                             "metric that vision carries")
    parser.add_argument("--baselines", nargs="*", type=Path, metavar="CHECKPOINT",
                        help="also evaluate baseline checkpoints on the same trajectories and views, their rows beside the "
                             "model's (given without a checkpoint: the bundled baselines, "
                             f"{' and '.join(f'models/{name}' for name in BASELINES)})")
    parser.add_argument("--out", type=Path, help="folder for results.json and results.md (results of an earlier run "
                                                 "there are replaced only with --overwrite: choose a new folder to keep them)")
    parser.add_argument("--video", action="store_true", help="also write a comparison video per trajectory into OUT")
    parser.add_argument("--hand3d", action="store_true", help="with --video: add the pressure painted on 3D hands "
                                                              "(measured | predicted) to the videos (default: off)")
    add_rerun_arguments(parser, serve=False)
    add_overwrite_argument(parser, "--out's results.json and results.md, or --rerun")
    parser.set_defaults(run=run)


def trajectory_frames(episode, prediction, gt, hand3d: bool = False, used: tuple[str, ...] = VIEW_NAMES):
    """Comparison frames of one evaluated trajectory (stitched prediction against ground truth); `hand3d`: with
    the pressure painted on the 3D hands (the episode's WiLoR poses); `used`: the views the model took anything
    from (the others are marked "not used")."""
    from touchanything.viz.comparison_video import comparison_frame
    from touchanything.viz.hand3d_panel import hand3d_panel

    for i in range(episode.num_frames):
        images = {v: s.read(i) for v, s in episode.views.items()}
        footer = f"Frame {i:04d}/{episode.num_frames}  t={episode.timestamps_us[i] / 1e6:.2f}s  [{episode.task}/{episode.trajectory_id}]"
        shown = np.where(np.isnan(gt[i]), np.nan, prediction[i])  # the ground truth's layout mask, as officially
        hands = None
        if hand3d and episode.wilor is not None:
            hands = hand3d_panel(episode.wilor.joints[i].reshape(42, 3), episode.wilor.valid[i], gt[i], shown)
        yield comparison_frame({v: im for v, im in images.items() if im is not None}, gt[i], shown, footer, hand3d=hands,
                               used=used)


def split_files(data: Path, split: str, split_file: Path | None, num_traj: int | None) -> list[Path]:
    from touchanything.devices.episodes.episode_loader import episode_exists

    if split_file is None and not (data / SPLIT_FILE).exists():
        raise UserError(f"{data / SPLIT_FILE}: not found; make one with `touchanything split {data}`, or name a split "
                        "file with --split-file")
    files = read_split(split_file or data / SPLIT_FILE)[split]
    if num_traj is not None:
        if num_traj < 1:
            raise UserError(f"--num-traj must be at least 1, got {num_traj}")
        files = files[:num_traj]
    missing = [f for f in files if not episode_exists(f)]
    if missing:
        raise UserError(f"{missing[0]}: listed in the split but not found ({len(missing)} missing)")
    if not files:
        raise UserError(f"split {split!r} is empty")
    return files


def _frame_count(path: Path) -> int:
    """The trajectory's frames for the progress bar's total; 0 for one that cannot be read (the evaluation
    names it and goes on)."""
    from touchanything.devices.episodes.episode_loader import open_episode

    try:
        with open_episode(path) as episode:
            return episode.num_frames
    except Exception:  # noqa: BLE001 - any failure is the evaluation's to report, not the progress bar's
        return 0


def _evaluate_views(args: argparse.Namespace, model, files: list[Path], views: str, group: ProcessGroup,
                    blank: bool = False, name: str = "", recordings: TrajectoryRecordings | None = None) -> EvaluationResult:
    """One view configuration (`blank`: its pose-only twin; `name`: a baseline's); `recordings`: each trajectory
    into the Rerun recording. The progress bar (main process) shows the frames encoded out of this process's
    total, frames/s and trajectories done."""
    from tqdm import tqdm

    from touchanything.inference.evaluation.evaluation import evaluate
    from touchanything.viz.comparison_video import write_comparison_video

    mine = files[group.rank::group.world]
    finished = []
    suffix = f"_{name}" if name else "_pose_only" if blank else ""
    used = views_used(VIEW_SETS[views], blank or model.config.blank_images)
    total = sum(_frame_count(f) for f in mine) if group.is_main else None
    with tqdm(total=total, unit=" frames", desc=f"eval {views}{suffix.replace('_', ' ')}", disable=not group.is_main) as bar:
        def done(row, episode, prediction, gt) -> None:
            label = f"{episode.scene}_{episode.task}_{episode.trajectory_id}_{views}{suffix}"
            if args.video:
                write_comparison_video(args.out / f"{label}.mp4", trajectory_frames(episode, prediction.stitched, gt, args.hand3d,
                                                                                    used))
            if recordings is not None:
                recordings.add(label, episode, prediction.stitched, gt, used)
            finished.append(row)
            bar.set_postfix(trajectories=f"{len(finished)}/{len(mine)}")

        return evaluate(model, files, views, args.batch_size, args.ego_path, args.precision, group,
                        on_trajectory=done, on_frames=lambda n: bar.update(int(n)), blank=blank)


def pose_only_model(args: argparse.Namespace, model: TactileModel, device) -> tuple[Path | None, TactileModel | None]:
    """The checkpoint and model of the pose-only rows: none; CHECKPOINT of `--pose-only-baseline CHECKPOINT`; without
    one, the evaluated model's bundled twin trained on black frames (models/nano → models/nano_pose_only) when
    there is one, else the evaluated model itself."""
    from touchanything.app.sessions.bundled import pose_only_twin
    from touchanything.inference.model.checkpoint import load_model

    if args.pose_only_baseline is None:
        return None, None
    if args.pose_only_baseline is True and (twin := pose_only_twin(args.checkpoint)) is not None:
        print(f"pose-only rows: {twin}, the model's twin trained on black frames")
        return twin, load_model(twin).to(device)
    if args.pose_only_baseline is True or args.pose_only_baseline == args.checkpoint:
        return args.checkpoint, model
    return args.pose_only_baseline, load_model(args.pose_only_baseline).to(device)


def baseline_models(args: argparse.Namespace, device) -> dict[str, tuple[Path, TactileModel]]:
    """name → (checkpoint, model) of `--baselines` (none without the flag; the bundled ones when it is given
    empty), loaded before any evaluation."""
    from touchanything.inference.model.checkpoint import load_model

    if args.baselines is None:
        return {}
    checkpoints = {path.parent.name: path for path in args.baselines} if args.baselines else bundled_baselines()
    if not checkpoints:
        raise UserError(f"--baselines: no bundled baselines under {MODELS_DIR}; name their checkpoints")
    return {name: (path, load_model(path).to(device)) for name, path in checkpoints.items()}


def view_configurations(chosen: list[tuple[str, ...]]) -> list[str]:
    """The official configuration names of the `--views` values, each once, in the given order; a set that is
    not one of them (every configuration includes ego) is a user error."""
    names = list(dict.fromkeys(view_set_name(views) for views in chosen))
    if odd := [n for n in names if n not in VIEW_SETS]:
        raise UserError(f"--views {odd[0]}: the official view configurations are {', '.join(VIEW_SETS)} "
                        "(ego is always in)")
    return names


def run(args: argparse.Namespace) -> int:
    from touchanything.app.sessions.rerun_trajectories import TrajectoryRecordings
    from touchanything.inference.model.checkpoint import load_model

    configurations = view_configurations(args.views)
    if args.batch_size < 1:
        raise UserError(f"--batch-size must be at least 1, got {args.batch_size}")
    if args.video and not args.out:
        raise UserError("--video needs --out (the folder the videos go to)")
    inputs = (args.checkpoint, args.config, args.data, args.split_file, *(args.baselines or ()),
              args.pose_only_baseline if isinstance(args.pose_only_baseline, Path) else None)
    if args.out:
        check_report_folder(args.out, RESULT_FILES, inputs, keep=True, overwrite=args.overwrite)
    if args.rerun is not None:
        check_rrd_output(args.rerun, args.overwrite, inputs)
    files = split_files(args.data, args.split, args.split_file, args.num_traj)
    group = join_process_group(args.device)
    if args.rerun is not None and group.world > 1:
        raise UserError("--rerun records in one process; run eval without torchrun for a recording")
    device = resolve_device(args.device, group.local_rank)
    check_precision(args.precision, device)
    model = load_model(args.checkpoint, args.config).to(device)
    baseline, baseline_model = pose_only_model(args, model, device)
    baselines = baseline_models(args, device)
    if group.is_main:
        print(f"eval on {device_label(device)}, {args.precision}, {len(files)} trajectories"
              + (f" over {group.world} processes" if group.world > 1 else ""))
    results = []
    recordings = args.rerun and TrajectoryRecordings(args.rerun, TactileLayout.default().bend, {"checkpoint": str(args.checkpoint)})
    try:
        for views in configurations:
            results.append(_evaluate_views(args, model, files, views, group, recordings=recordings))
            if baseline_model is not None:
                results.append(_evaluate_views(args, baseline_model, files, views, group, blank=True, recordings=recordings))
            for name, (_, other) in baselines.items():
                result = _evaluate_views(args, other, files, views, group, name=name, recordings=recordings)
                results.append(dataclasses.replace(result, baseline=name))
    finally:
        if recordings is not None:
            recordings.close()
    if not group.is_main:
        return 0
    failures = list(dict.fromkeys(line for result in results for line in result.failures))
    for line in failures:
        print(f"touchanything eval: failed: {line}", file=sys.stderr)
    checkpoints = {n: str(c) for n, (c, _) in baselines.items()}
    table = markdown(results, args.split, baseline and str(baseline), checkpoints)
    print(table)
    if args.out:
        write_text(args.out / RESULT_FILES[0], results_json(results, args.split, str(args.checkpoint), args.ego_path,
                                                            baseline and str(baseline), checkpoints))
        write_text(args.out / RESULT_FILES[1], table)
        print(f"results: {args.out / 'results.json'}, {args.out / 'results.md'}")
    if args.rerun is not None:
        print(f"rerun: {args.rerun} ({len(recordings.parts)} recordings; open with: rerun {args.rerun})")
    if failures:
        print(f"touchanything eval: {len(failures)} of {len(files)} trajectories could not be evaluated (listed above)",
              file=sys.stderr)
    return 1 if failures else 0
