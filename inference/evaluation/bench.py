"""`touchanything bench`: latency, throughput, memory and accuracy of every engine setting of a model.

Per model: each setting (`bench_setting.settings_for`) replays the held-out trajectories frame by frame
(`bench_accuracy`: official metrics per trajectory, agreement with the reference setting's outputs,
throughput), then all settings take turns on a full-resolution clip (interleaved rounds after a warm-up round)
for per-frame latency p50/p99. The naive baseline recomputes the whole 8-frame clip every frame;
`naive_over_streaming` is its per-frame time over the streaming engine's (torch fp32, all views), per model.
With `BenchPlan.pose_only`, each setting is followed by its pose-only twin: the same engine replaying the same
trajectories with every frame black (`preprocess.blank_images`), accuracy only (the engine's work does not
depend on the pixels), with the share of each metric that vision carries (`vision_share`). Intervals and
paired comparisons are added over all models' rows by `bench_intervals`.
"""
from __future__ import annotations

import dataclasses
import tempfile
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from touchanything.core.snapshot import VIEW_NAMES, Snapshot
from touchanything.core.view_sets import view_set_name
from touchanything.inference.engine.engine_runtime import Runtime
from touchanything.inference.engine.engine_setting import EngineSetting, compute_threads
from touchanything.inference.engine.ensemble_engine import engine_for
from touchanything.inference.engine.onnx_export import export_onnx
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench_accuracy import HeldOut, ModelAccuracy, SettingAccuracy, model_accuracy
from touchanything.inference.evaluation.bench_data import resident_mb
from touchanything.inference.evaluation.bench_intervals import SPREAD_ERROR
from touchanything.inference.evaluation.bench_setting import settings_for
from touchanything.inference.evaluation.metrics import aggregate
from touchanything.inference.evaluation.vision_share import vision_shares
from touchanything.inference.model.ensemble_members import member_count
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import resize_frame, to_model_input
from touchanything.inference.model.torch_device import device_label

PER_TRAJECTORY_METRICS = ("volumetric_iou", "contact_iou", "temporal_accuracy", "mae")
"""The per-trajectory values each row keeps (for intervals and paired comparisons, also across runs)."""


def interleaved_latency(engines: dict[EngineSetting, StreamingEngine], clip: list[Snapshot], rounds: int,
                        per_round: int, progress=lambda message: None) -> dict[EngineSetting, tuple[np.ndarray, float]]:
    """Per-frame step times (ms) and peak resident MB per setting; round 0 warms up and is discarded; `progress`
    after each round."""
    times = {s: [] for s in engines}
    peaks = {s: 0.0 for s in engines}
    counters = {s: 0 for s in engines}
    for round_index in range(rounds + 1):
        if round_index:
            progress(f"  latency round {round_index}/{rounds}")
        for setting, engine in engines.items():
            for _ in range(per_round):
                frame = clip[counters[setting] % len(clip)]
                snapshot = dataclasses.replace(frame, frame_index=counters[setting], t_us=int(time.monotonic() * 1e6))
                start = time.perf_counter()
                engine.step(snapshot)
                elapsed = (time.perf_counter() - start) * 1000
                counters[setting] += 1
                if round_index:
                    times[setting].append(elapsed)
                    peaks[setting] = max(peaks[setting], resident_mb())
    return {s: (np.array(times[s]), peaks[s]) for s in engines}


@torch.inference_mode()
def naive_latency(model: TactileModel, clip: list[Snapshot], steps: int, warmup: int = 1) -> np.ndarray:
    """Per-frame ms of recomputing the whole clip (all views, batch forward) for every new frame; each frame
    is preprocessed once and kept, as a sensible non-caching implementation would."""
    size, history, times = model.config.image_size, deque(maxlen=SPAN), []
    model.eval()
    for step in range(warmup + steps):
        snapshot = clip[step % len(clip)]
        start = time.perf_counter()
        images = np.stack([resize_frame(snapshot.images[v], size) for v in VIEW_NAMES])
        pose = prepare_poses(np.asarray(snapshot.joints).reshape(42, 3), np.asarray(snapshot.joints_valid))
        history.append((to_model_input(images), torch.from_numpy(pose)))
        picks = [history[max(len(history) - 1 - FRAME_INTERVAL * k, 0)] for k in range(CLIP_LENGTH - 1, -1, -1)]
        views = {v: torch.stack([p[0][i] for p in picks])[None] for i, v in enumerate(VIEW_NAMES)}
        model(poses=torch.stack([p[1] for p in picks])[None], views=views)
        if step >= warmup:
            times.append((time.perf_counter() - start) * 1000)
    return np.array(times)


@dataclass
class BenchPlan:
    """rounds × per_round latency frames per setting; naive_steps naive clip recomputations per model;
    pose_only: each setting's pose-only baseline too."""

    quick: bool
    rounds: int
    per_round: int
    naive_steps: int
    pose_only: bool = False


def accuracy_fields(result: SettingAccuracy) -> dict:
    """A row's accuracy: the official metrics (mean over trajectories), agreement with the reference outputs,
    throughput, peak memory and the per-trajectory values of `PER_TRAJECTORY_METRICS` (and, for an ensemble, of
    `SPREAD_ERROR`)."""
    metrics = aggregate(result.per_trajectory)
    kept = PER_TRAJECTORY_METRICS + ((SPREAD_ERROR,) if any(SPREAD_ERROR in t for t in result.per_trajectory) else ())
    return {"contact_iou": metrics["contact_iou"], "volumetric_iou": metrics["volumetric_iou"], "metrics": metrics,
            "agreement_viou": result.agreement_viou, "agreement_max_abs": result.worst, "peak_rss_mb": result.peak_mb,
            "throughput_fps": result.throughput_fps,
            "per_trajectory": {m: [t.get(m, float("nan")) for t in result.per_trajectory] for m in kept}}


def setting_row(setting: EngineSetting, runtime: Runtime, checkpoint_sha256: str | None = None) -> dict:
    """A row's description of its setting, latency and accuracy not measured (None); `runtime` (the engine's,
    after the run) names device and capture; `checkpoint_sha256` the weights it ran (None: not from a file)."""
    gpu = torch.cuda.get_device_name(runtime.device) if runtime.device.type == "cuda" else None
    return {"setting": setting.name(), "model": setting.model, "checkpoint_sha256": checkpoint_sha256,
            "runtime": setting.runtime, "precision": setting.precision,
            "device": device_label(runtime.device), "gpu_name": gpu, "capture": runtime.capture,
            "views": view_set_name(setting.views), "every": setting.every, "output": setting.output,
            "invalid_hands": setting.invalid_hands, "blank": setting.blank,
            "threads": compute_threads(), "lookahead_ms": setting.lookahead_ms,
            "p50_ms": None, "p99_ms": None, "mean_ms": None, "latency_frames": 0, "trajectories": 0,
            "contact_iou": None, "volumetric_iou": None, "agreement_viou": None, "peak_rss_mb": 0.0}


def latency_row(setting: EngineSetting, times: np.ndarray, peak_mb: float, runtime: Runtime,
                checkpoint_sha256: str | None = None) -> dict:
    """The row of one setting's latency (`setting_row` with the step times in ms)."""
    return {**setting_row(setting, runtime, checkpoint_sha256), "p50_ms": float(np.percentile(times, 50)),
            "p99_ms": float(np.percentile(times, 99)), "mean_ms": float(times.mean()), "latency_frames": int(times.size),
            "peak_rss_mb": peak_mb}


@dataclass
class ModelBench:
    """One model's rows, its naive comparison {naive_p50_ms, streaming_p50_ms, ratio}, and the held-out
    trajectories its accuracy covers (names and splits, in row order; empty without held-out data) with the
    ones that could not be loaded."""

    rows: list[dict]
    naive: dict
    trajectories: list[dict]
    failures: list[str]


def bench_model(name: str, model: TactileModel, held_out: HeldOut | None, clip: list[Snapshot], plan: BenchPlan,
                progress=print, checkpoint: Path | None = None, checkpoint_sha256: str | None = None) -> ModelBench:
    """Every setting of one model: accuracy on `held_out` (None: latency only, torch fp32 all views), then
    interleaved latency, then the naive comparison. `checkpoint` (the file the model came from) is what worker
    processes load; `checkpoint_sha256` is recorded in every row."""
    members = member_count(checkpoint) if checkpoint is not None else 1
    settings = (settings_for(name, plan.quick, plan.pose_only, members) if held_out is not None
                else [EngineSetting(name, device="cpu")])
    with tempfile.TemporaryDirectory(prefix="touchanything-bench-") as folder:
        onnx_dir = Path(folder)
        if any(s.runtime == "onnx" for s in settings):
            progress(f"{name}: exporting ONNX graphs")
            export_onnx(model, onnx_dir, int8=True)
        engines = {s: engine_for(model, checkpoint, s, onnx_dir if s.runtime == "onnx" else None)
                   for s in settings if not s.blank}
        accuracy = (model_accuracy(model, checkpoint, settings, engines, onnx_dir, held_out, progress)
                    if held_out is not None else ModelAccuracy([], [], {}, []))
        progress(f"{name}: interleaved latency ({plan.rounds} rounds × {plan.per_round} frames per setting)")
        latency = interleaved_latency(engines, clip, plan.rounds, plan.per_round, progress)
    rows = []
    for setting in settings:
        runtime = engines[dataclasses.replace(setting, blank=False)].runtime
        times, peak = latency.get(setting, (None, 0.0))
        row = (setting_row(setting, runtime, checkpoint_sha256) if times is None
               else latency_row(setting, times, peak, runtime, checkpoint_sha256))
        if setting in accuracy.settings:
            row.update(accuracy_fields(accuracy.settings[setting]), trajectories=len(accuracy.names))
            row["peak_rss_mb"] = max(peak, row["peak_rss_mb"])
        rows.append(row)
    for row, setting in zip(rows, settings):
        if setting.blank:
            twin = rows[settings.index(dataclasses.replace(setting, blank=False))]
            row["vision_share"] = vision_shares(twin["metrics"], row["metrics"])
    progress(f"{name}: naive recompute ({plan.naive_steps} frames)")
    naive = float(np.median(naive_latency(model, clip, plan.naive_steps)))
    streaming = rows[0]["p50_ms"]
    trajectories = [{"name": n, "split": s} for n, s in zip(accuracy.names, accuracy.splits)]
    return ModelBench(rows, {"naive_p50_ms": naive, "streaming_p50_ms": streaming, "ratio": naive / streaming},
                      trajectories, accuracy.failures)
