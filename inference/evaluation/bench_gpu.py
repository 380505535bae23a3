"""`touchanything bench --device cuda`: the accurate tier where it runs — per-frame latency of the `paper` and
`small` presets (random weights: latency does not depend on them) in fp32 / bf16 / fp16, three views and ego
only, with CUDA graphs and eagerly, and the naive full-clip recompute, all on one device in one process.

The same code runs on the CPU (fp16 left out, every call eager), which is how CI tests it.
"""
from __future__ import annotations

import time
from collections import deque

import numpy as np
import torch

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench import interleaved_latency, latency_row
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN, preset
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import model_input, model_input_on_device
from touchanything.inference.model.torch_device import autocast, device_label
from touchanything.inference.model.touch_model import TouchAnything

GPU_PRESETS = ("paper", "small")
VIEW_SETTINGS = (VIEW_NAMES, ("ego",))


def gpu_settings(name: str, device: torch.device) -> list[EngineSetting]:
    """Precisions the device offers (tf32 and fp16 on a GPU) × three views / ego only × captured / eager, torch
    newest-frame output."""
    precisions = ("fp32", "tf32", "bf16", "fp16") if device.type == "cuda" else ("fp32", "bf16")
    return [EngineSetting(name, precision=p, views=v, device=str(device), capture=c)
            for p in precisions for v in VIEW_SETTINGS for c in (True, False)]


@torch.inference_mode()
def naive_latency_on(model: TouchAnything, clip: list[Snapshot], steps: int, device: torch.device,
                     precision: str) -> np.ndarray:
    """Per-frame ms of the naive baseline on `device`: each frame prepared once (on the device for a GPU),
    then the whole 8-frame clip recomputed; the output is copied to the host, as a prediction must be."""
    size, history, times = model.config.image_size, deque(maxlen=SPAN), []
    prepare = (lambda f: model_input_on_device(f, size, device)) if device.type == "cuda" else (
        lambda f: torch.from_numpy(model_input(f, size)))
    for step in range(1 + steps):
        snapshot = clip[step % len(clip)]
        start = time.perf_counter()
        pose = prepare_poses(np.asarray(snapshot.joints).reshape(42, 3), np.asarray(snapshot.joints_valid))
        history.append((prepare([snapshot.images[v] for v in VIEW_NAMES]).to(device), torch.from_numpy(pose).to(device)))
        picks = [history[max(len(history) - 1 - FRAME_INTERVAL * k, 0)] for k in range(CLIP_LENGTH - 1, -1, -1)]
        views = {v: torch.stack([p[0][i] for p in picks])[None] for i, v in enumerate(VIEW_NAMES)}
        with autocast(device, precision):
            model(poses=torch.stack([p[1] for p in picks])[None], views=views)["tactile"].float().cpu()
        if step:
            times.append((time.perf_counter() - start) * 1000)
    return np.array(times)


def bench_presets_on(device: torch.device, clip: list[Snapshot], rounds: int, per_round: int, naive_steps: int,
                     presets: tuple[str, ...] = GPU_PRESETS, progress=print) -> tuple[list[dict], dict]:
    """Latency rows (with `device`, `gpu_name`, `capture`, `peak_gpu_mb`) of every `gpu_settings` of each
    preset, and {"<preset> <precision>": naive p50 ms} per preset and precision."""
    rows, naive = [], {}
    for name in presets:
        torch.manual_seed(0)
        model = TouchAnything(preset(name)).eval().to(device)
        settings = gpu_settings(name, device)
        engines = {s: StreamingEngine(model, s) for s in settings}
        progress(f"{name} on {device_label(device)}: {len(settings)} settings, {rounds} rounds × {per_round} frames")
        if device.type == "cuda":
            torch.cuda.reset_peak_memory_stats(device)
        for setting, (times, peak) in interleaved_latency(engines, clip, rounds, per_round).items():
            row = latency_row(setting, times, peak, engines[setting].runtime)
            row["peak_gpu_mb"] = torch.cuda.max_memory_allocated(device) / 1e6 if device.type == "cuda" else None
            rows.append(row)
        for precision in dict.fromkeys(s.precision for s in settings):
            progress(f"{name} {precision}: naive recompute ({naive_steps} frames)")
            naive[f"{name} {precision}"] = float(np.median(naive_latency_on(model, clip, naive_steps, device, precision)))
        del engines, model
    return rows, naive


def gpu_markdown(record: dict) -> str:
    """The GPU bench as Markdown: a row per setting, then the naive recompute per preset and precision."""
    lines = ["# `touchanything bench --device cuda`", "", f"{record['machine']}; device {record['device']}.", "",
             "| setting | capture | p50 ms | p99 ms | peak GPU MB |", "|---|---|---|---|---|"]
    for r in record["rows"]:
        gpu_mb = "n/a" if r.get("peak_gpu_mb") is None else f"{r['peak_gpu_mb']:.0f}"
        lines.append(f"| {r['setting']} | {r['capture']} | {r['p50_ms']:.1f} | {r['p99_ms']:.1f} | {gpu_mb} |")
    lines += ["", "## Naive full-clip recompute (three views)", "", "| preset, precision | p50 ms |", "|---|---|"]
    lines += [f"| {key} | {value:.1f} |" for key, value in record["naive"].items()]
    return "\n".join(lines) + "\n"
