"""`touchanything bench`: the speed/accuracy table of every engine setting (Markdown, JSON, Pareto plot)."""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import onnxruntime
import torch

from touchanything.app.sessions.bundled import MODELS_DIR, OUTPUT_DIR, SAMPLE_DIR, bundled_models
from touchanything.app.sessions.engine_choice import add_device_argument
from touchanything.devices.errors import UserError
from touchanything.devices.output_safety import check_report_folder, write_text
from touchanything.inference.evaluation.bench import BenchPlan, bench_model
from touchanything.inference.evaluation.bench_data import episode_paths, first_latency_clip, load_episodes
from touchanything.inference.evaluation.bench_gpu import bench_presets_on, gpu_markdown
from touchanything.inference.evaluation.bench_report import (
    GPU_OUTPUT_FILES,
    OUTPUT_FILES,
    markdown,
    target_checks,
    write_outputs,
)
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.model_config import preset
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.torch_device import device_label, resolve_device
from touchanything.inference.model.touch_model import TouchAnything

LATENCY_CLIP_FRAMES = 60


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("bench", help="measure latency, memory and accuracy of every engine setting")
    parser.add_argument("--quick", action="store_true",
                        help="smallest bundled model (torch fp32, ONNX int8) and the paper preset's cache gain")
    parser.add_argument("--out", type=Path, default=OUTPUT_DIR / "bench",
                        help=f"folder for engine.{{json,md}} and the plot (default {OUTPUT_DIR / 'bench'} in the working "
                             "directory; the committed results are docs/bench)")
    parser.add_argument("--data", type=Path, default=SAMPLE_DIR,
                        help="held-out episodes with ground truth (default: the bundled sample)")
    parser.add_argument("--models", type=Path, nargs="+",
                        help="model folders holding best_model.pth (default: every bundled model)")
    parser.add_argument("--frames", type=int, help="accuracy on the first N frames of each episode (default: every frame; 150 with "
                                                            "--quick)")
    parser.add_argument("--pose-only-baseline", action="store_true",
                        help="after each setting, its accuracy with every frame black (pose only) and the share of "
                             "each metric that vision carries")
    add_device_argument(parser)
    parser.set_defaults(run=run)


def load_models(folders: list[Path] | None) -> dict[str, TactileModel]:
    """name → model for each folder (default: every bundled model), smallest first by parameter count."""
    folders = folders or sorted(checkpoint.parent for checkpoint in bundled_models().values())
    if not folders:
        raise UserError(f"{MODELS_DIR}: no bundled models; pass --models")
    models = {Path(f).name: load_model(Path(f) / "best_model.pth") for f in folders}
    return dict(sorted(models.items(), key=lambda item: sum(p.numel() for p in item[1].parameters())))


def machine() -> str:
    return (f"{os.cpu_count()} CPU cores ({platform.machine()}), torch {torch.__version__}, "
            f"onnxruntime {onnxruntime.__version__}")


def run_on_gpu(args: argparse.Namespace, device: torch.device) -> int:
    """The GPU settings (`bench_gpu`) into OUT/engine_gpu.{json,md}."""
    paths = episode_paths(args.data)
    clip = first_latency_clip(paths, LATENCY_CLIP_FRAMES)
    started = time.perf_counter()
    rounds, per_round, naive_steps = (2, 10, 10) if args.quick else (5, 30, 30)
    rows, naive = bench_presets_on(device, clip, rounds, per_round, naive_steps,
                                   progress=lambda m: print(f"[{time.perf_counter() - started:6.0f} s] {m}", file=sys.stderr))
    record = {"machine": machine(), "device": device_label(device), "quick": args.quick, "rows": rows, "naive": naive,
              "seconds": time.perf_counter() - started}
    json_path, markdown_path = (args.out / name for name in GPU_OUTPUT_FILES)
    write_text(json_path, json.dumps(record, indent=1) + "\n")
    write_text(markdown_path, gpu_markdown(record))
    print(gpu_markdown(record))
    print(f"written: {json_path}, {markdown_path}")
    return 0


def run(args: argparse.Namespace) -> int:
    device = resolve_device(args.device)
    check_report_folder(args.out, GPU_OUTPUT_FILES if device.type == "cuda" else OUTPUT_FILES,
                        (args.data, *(args.models or ())))
    if device.type == "cuda":
        if args.pose_only_baseline:
            raise UserError("--pose-only-baseline needs accuracy, which the GPU bench (latency only) does not measure; "
                            "use --device cpu")
        return run_on_gpu(args, device)
    frames = args.frames if args.frames is not None else (150 if args.quick else None)
    if frames is not None and frames < 15:
        raise UserError(f"--frames must be at least 15 (one 8-frame window), got {frames}")
    paths = episode_paths(args.data)
    models = load_models(args.models)
    if args.quick:
        models = dict(list(models.items())[:1])
    clip = first_latency_clip(paths, LATENCY_CLIP_FRAMES)
    started = time.perf_counter()
    rows, naive = [], {}

    def progress(message: str) -> None:
        print(f"[{time.perf_counter() - started:6.0f} s] {message}", file=sys.stderr, flush=True)

    failures: dict[str, None] = {}
    for name, model in models.items():
        episodes, failed = load_episodes(paths, model.config.image_size, frames)
        for line in failed:
            if line not in failures:
                progress(f"skipped: {line}")
            failures[line] = None
        plan = BenchPlan(args.quick, rounds=4 if args.quick else 20, per_round=10, naive_steps=10 if args.quick else 30,
                         pose_only=args.pose_only_baseline)
        model_rows, naive[name] = bench_model(name, model, episodes, clip, plan, progress)
        rows += model_rows
    torch.manual_seed(0)
    paper_plan = BenchPlan(args.quick, rounds=2, per_round=2, naive_steps=2 if args.quick else 4)
    paper_rows, naive["paper"] = bench_model("paper", TouchAnything(preset("paper")).eval(), None, clip, paper_plan, progress)
    rows += paper_rows
    record = {"machine": machine(), "quick": args.quick, "accuracy_data": str(args.data),
              "episodes": [str(p) for p in paths], "failed": list(failures), "frames_per_episode": frames,
              "seconds": time.perf_counter() - started,
              "rows": rows, "naive_over_streaming": {k: v["ratio"] for k, v in naive.items()}, "naive": naive,
              "targets": target_checks(rows, naive, next(iter(models)))}
    written = write_outputs(record, args.out)
    print(markdown(record))
    print("written: " + ", ".join(str(p) for p in written))
    for line in failures:
        print(f"touchanything bench: failed: {line}", file=sys.stderr)
    return 1 if failures else 0
