"""`touchanything bench`: the speed/accuracy atlas of every engine setting (Markdown, JSON, Pareto plot), and
with `--budget-ms` the most accurate setting that fits a latency budget on this machine."""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from touchanything.app.sessions.bundled import ATLAS_FILE, MODELS_DIR, OUTPUT_DIR, SAMPLE_DIR, bundled_models
from touchanything.app.sessions.engine_choice import DEFAULT_MODEL, add_device_argument
from touchanything.app.sessions.setting_choice import budget_request
from touchanything.core.errors import UserError
from touchanything.core.output_safety import add_overwrite_argument, check_report_folder, write_text
from touchanything.inference.evaluation.atlas import file_sha256
from touchanything.inference.evaluation.bench_intervals import add_intervals, align_rows, paired_comparisons
from touchanything.inference.evaluation.bench_report import (
    GPU_OUTPUT_FILES,
    OUTPUT_FILES,
    POSE_BASELINE,
    markdown,
    record_json,
    target_checks,
    write_outputs,
)
from touchanything.inference.evaluation.bootstrap import FEW_TRAJECTORIES, thin_strata
from touchanything.inference.model.torch_device import device_label, resolve_device

if TYPE_CHECKING:
    import torch

    from touchanything.inference.evaluation.bench_accuracy import HeldOut
    from touchanything.inference.model.models import TactileModel

LATENCY_CLIP_FRAMES = 60


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("bench", help="measure latency, memory and accuracy of every engine setting (the "
                                               "speed/accuracy atlas), or pick the setting that fits a latency budget")
    parser.add_argument("--quick", action="store_true",
                        help=f"the default model ({DEFAULT_MODEL}: torch fp32, ONNX int8) and the paper preset's cache "
                             "gain; with --budget-ms, a shorter latency probe")
    parser.add_argument("--out", type=Path, default=OUTPUT_DIR / "bench",
                        help=f"folder for engine.{{json,md}} and the plot (default {OUTPUT_DIR / 'bench'} in the working "
                             "directory; the bundled atlas is models/atlas, written with --out models/atlas --overwrite)")
    parser.add_argument("--data", type=Path, default=SAMPLE_DIR,
                        help="held-out trajectories with ground truth: a dataset root with a split.json (its test_seen and "
                             "test_unseen lists, or --splits), or a folder of episodes (default: the bundled sample)")
    parser.add_argument("--splits", nargs="+", metavar="SPLIT",
                        help="with a dataset root: the split lists to measure on, each kept apart (default test_seen "
                             "test_unseen)")
    parser.add_argument("--models", type=Path, nargs="+",
                        help="model folders holding best_model.pth (default: every bundled model)")
    parser.add_argument("--frames", type=int, help="accuracy on the first N frames of each episode (default: every frame; 150 with "
                                                            "--quick)")
    parser.add_argument("--workers", type=int, default=1,
                        help="replay the held-out trajectories for accuracy in N processes (latency is always measured in "
                             "one; default 1)")
    parser.add_argument("--pose-only-baseline", action="store_true",
                        help="after each setting, its accuracy with every frame black (pose only) and the share of "
                             "each metric that vision carries")
    parser.add_argument("--budget-ms", type=float, metavar="MS",
                        help="instead of the atlas: probe the settings' p99 latency here and print the most accurate one "
                             "(accuracy from --atlas) whose p99 fits MS, with the command that runs it; writes nothing")
    parser.add_argument("--atlas", type=Path, default=ATLAS_FILE,
                        help="with --budget-ms: the atlas to take accuracy from (default: the committed models/atlas/engine.json)")
    add_device_argument(parser)
    add_overwrite_argument(parser, "--out's engine.json, engine.md and plot (those an earlier bench wrote there are replaced anyway)")
    parser.set_defaults(run=run)


def load_models(folders: list[Path] | None) -> dict[str, tuple[TactileModel, Path]]:
    """name → (model, checkpoint) for each folder (default: every bundled model), smallest first by parameter
    count."""
    from touchanything.inference.model.checkpoint import load_model

    folders = folders or sorted(checkpoint.parent for checkpoint in bundled_models().values())
    if not folders:
        raise UserError(f"{MODELS_DIR}: no bundled models; pass --models")
    models = {Path(f).name: (load_model(Path(f) / "best_model.pth"), Path(f) / "best_model.pth") for f in folders}
    return dict(sorted(models.items(), key=lambda item: sum(p.numel() for p in item[1][0].parameters())))


def machine() -> str:
    import onnxruntime
    import torch

    return (f"{os.cpu_count()} CPU cores ({platform.machine()}), torch {torch.__version__}, "
            f"onnxruntime {onnxruntime.__version__}")


def run_on_gpu(args: argparse.Namespace, device: torch.device) -> int:
    """The GPU settings (`bench_gpu`) into OUT/engine_gpu.{json,md}."""
    from touchanything.inference.evaluation.bench_data import first_latency_clip, held_out_paths
    from touchanything.inference.evaluation.bench_gpu import bench_presets_on, gpu_markdown

    paths = [path for path, _ in held_out_paths(args.data, args.splits)]
    clip = first_latency_clip(paths, LATENCY_CLIP_FRAMES)
    started = time.perf_counter()
    rounds, per_round, naive_steps = (2, 10, 10) if args.quick else (5, 30, 30)
    rows, naive = bench_presets_on(device, clip, rounds, per_round, naive_steps,
                                   progress=lambda m: print(f"[{time.perf_counter() - started:6.0f} s] {m}", file=sys.stderr))
    record = {"machine": machine(), "device": device_label(device), "quick": args.quick, "rows": rows, "naive": naive,
              "seconds": time.perf_counter() - started}
    json_path, markdown_path = (args.out / name for name in GPU_OUTPUT_FILES)
    write_text(json_path, record_json(record))
    write_text(markdown_path, gpu_markdown(record))
    print(gpu_markdown(record))
    print(f"written: {json_path}, {markdown_path}")
    return 0


def check_arguments(args: argparse.Namespace) -> int | None:
    """The frames per episode (None: all); UserError for a bad number."""
    if args.workers < 1:
        raise UserError(f"--workers must be at least 1, got {args.workers}")
    frames = args.frames if args.frames is not None else (150 if args.quick else None)
    if frames is not None and frames < 15:
        raise UserError(f"--frames must be at least 15 (one 8-frame window), got {frames}")
    return frames


def run(args: argparse.Namespace) -> int:
    from touchanything.inference.evaluation.bench_accuracy import HeldOut
    from touchanything.inference.evaluation.bench_data import held_out_paths

    device = resolve_device(args.device)
    if args.budget_ms is not None:
        return budget(args)
    check_report_folder(args.out, GPU_OUTPUT_FILES if device.type == "cuda" else OUTPUT_FILES,
                        (args.data, *(args.models or ())), overwrite=args.overwrite)
    if device.type == "cuda":
        if args.pose_only_baseline:
            raise UserError("--pose-only-baseline needs accuracy, which the GPU bench (latency only) does not measure; "
                            "use --device cpu")
        return run_on_gpu(args, device)
    frames = check_arguments(args)
    pairs = held_out_paths(args.data, args.splits)
    models = load_models(args.models)
    if args.quick:
        name = DEFAULT_MODEL if DEFAULT_MODEL in models else next(iter(models))
        models = {name: models[name]}
    return atlas(args, models, HeldOut(pairs, frames, args.workers))


def atlas(args: argparse.Namespace, models: dict[str, tuple[TactileModel, Path]], held_out: HeldOut) -> int:
    import torch

    from touchanything.inference.evaluation.bench import BenchPlan, bench_model
    from touchanything.inference.evaluation.bench_data import first_latency_clip
    from touchanything.inference.model.model_config import preset
    from touchanything.inference.model.touch_model import TouchAnything

    clip = first_latency_clip([path for path, _ in held_out.pairs], LATENCY_CLIP_FRAMES)
    if len(held_out.pairs) < FEW_TRAJECTORIES:  # said once the data read (an error stays one line)
        print(f"warning: only {len(held_out.pairs)} held-out trajectories: the 95 % intervals are wide (use a dataset "
              f"root with at least {FEW_TRAJECTORIES}, e.g. data/heldout from scripts/make_datasets.sh)", file=sys.stderr)
    elif thin := thin_strata([split for _, split in held_out.pairs]):
        print(f"warning: {thin}", file=sys.stderr)
    started = time.perf_counter()

    def progress(message: str) -> None:
        print(f"[{time.perf_counter() - started:6.0f} s] {message}", file=sys.stderr, flush=True)

    rows, naive, trajectories, failures = [], {}, [], {}
    for name, (model, checkpoint) in models.items():
        plan = BenchPlan(args.quick, rounds=4 if args.quick else 20, per_round=10, naive_steps=10 if args.quick else 30,
                         pose_only=args.pose_only_baseline)
        result = bench_model(name, model, held_out, clip, plan, progress, checkpoint, file_sha256(checkpoint))
        for line in result.failures:
            if line not in failures:
                progress(f"skipped: {line}")
            failures[line] = None
        trajectories += [t for t in result.trajectories if t not in trajectories]
        rows.append((result.rows, result.trajectories))
        naive[name] = result.naive
    if not trajectories:
        raise UserError(f"no held-out trajectory could be loaded for the accuracy benchmark ({next(iter(failures))})")
    for model_rows, own in rows:
        align_rows(model_rows, own, trajectories)
    rows = [row for model_rows, _ in rows for row in model_rows]
    torch.manual_seed(0)
    paper_plan = BenchPlan(args.quick, rounds=2, per_round=2, naive_steps=2 if args.quick else 4)
    paper = bench_model("paper", TouchAnything(preset("paper")).eval(), None, clip, paper_plan, progress)
    rows += paper.rows
    naive["paper"] = paper.naive
    add_intervals(rows, trajectories)
    base = DEFAULT_MODEL if DEFAULT_MODEL in models else next(iter(models))
    record = {"machine": machine(), "quick": args.quick, "accuracy_data": str(args.data),
              "splits": list(dict.fromkeys(t["split"] for t in trajectories)), "trajectories": trajectories,
              "failed": list(failures), "frames_per_episode": held_out.frames, "workers": held_out.workers,
              "seconds": time.perf_counter() - started, "base_model": base,
              "rows": rows, "comparisons": paired_comparisons(rows, trajectories, (base, POSE_BASELINE)),
              "naive_over_streaming": {k: v["ratio"] for k, v in naive.items()}, "naive": naive}
    record["targets"] = target_checks(rows, naive, next(iter(models)), base, record["comparisons"])
    written = write_outputs(record, args.out)
    print(markdown(record))
    print("written: " + ", ".join(str(p) for p in written))
    for line in failures:
        print(f"touchanything bench: failed: {line}", file=sys.stderr)
    return 1 if failures else 0


def budget(args: argparse.Namespace) -> int:
    """`--budget-ms`: the choice (`setting_choice`) and the command that runs it."""
    choice = budget_request(args.atlas, args.budget_ms, args.models).pick(args.device, args.quick)
    print(choice.line)
    atlas = "" if args.atlas == ATLAS_FILE else f" --atlas {args.atlas}"
    print(f"run it:  touchanything demo --setting {choice.row.name}{atlas}   (or replay EPISODE / live --scene FILE with "
          "the same --setting)")
    return 0
