"""`touchanything bench`: latency, throughput, memory and accuracy of every engine setting, in one process.

Per model: each setting replays the held-out episodes frame by frame (official metrics against the ground
truth, agreement with the fp32 reference setting's outputs, throughput), then all settings take turns on
a full-resolution clip (interleaved rounds after a warm-up round) for per-frame latency p50/p99. The naive
baseline recomputes the whole 8-frame clip every frame; `naive_over_streaming` is its per-frame time over
the streaming engine's (torch fp32, all views), per model. With `BenchPlan.pose_only`, each setting is
followed by its pose-only baseline: the same engine replaying the same episodes with every frame black
(`preprocess.blank_images`), accuracy only (the engine's work does not depend on the pixels), with the share of
each metric that vision carries (`vision_share`).
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

from touchanything.devices.snapshot import VIEW_NAMES, Snapshot
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_config import EngineConfig
from touchanything.inference.engine.engine_runtime import Runtime
from touchanything.inference.engine.onnx_export import export_onnx
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench_data import BenchEpisode, resident_mb
from touchanything.inference.evaluation.evaluation import trajectory_metrics
from touchanything.inference.evaluation.metrics import aggregate
from touchanything.inference.evaluation.vision_share import vision_shares
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import blank_images, resize_frame, to_model_input
from touchanything.inference.model.torch_device import device_label

LOOKAHEAD_FRAMES = {"newest": 0, "centre": 6, "stitched": 14}


@dataclass(frozen=True)
class BenchSetting:
    model: str
    runtime: str = "torch"
    precision: str = "fp32"
    views: tuple[str, ...] = VIEW_NAMES
    rate: int = 1
    output: str = "newest"
    invalid_hands: str = "skip"
    device: str = "cpu"
    capture: bool = True
    blank: bool = False

    def label(self) -> str:
        views = "+".join(v.replace("wrist_", "") for v in self.views)
        extra = "".join([f" every {self.rate}" if self.rate > 1 else "", f" {self.output}" if self.output != "newest" else "",
                         " official-invalid" if self.invalid_hands == "official" else "",
                         " eager" if not self.capture else "", " pose only" if self.blank else ""])
        return f"{self.model} {self.runtime}-{self.precision} {views}{extra}"

    def engine_config(self, onnx_dir: Path | None) -> EngineConfig:
        return EngineConfig(runtime=self.runtime, precision=self.precision, onnx_dir=onnx_dir, views=self.views,
                            output=self.output, every=self.rate, invalid_hands=self.invalid_hands, device=self.device,
                            capture=self.capture)


def settings_for(model: str, quick: bool, pose_only: bool = False) -> list[BenchSetting]:
    """The reference (torch fp32, all views) first, then one knob at a time around it; with `pose_only`, each
    followed by its pose-only baseline (`blank`)."""
    base = BenchSetting(model)
    int8 = dataclasses.replace(base, runtime="onnx", precision="int8")
    partial_views = [("ego",), ("ego", "wrist_left"), ("ego", "wrist_right")]
    settings = [base, int8] if quick else (
        [base, dataclasses.replace(base, precision="bf16"), dataclasses.replace(base, runtime="onnx"), int8]
        + [dataclasses.replace(s, views=v) for s in (base, int8) for v in partial_views]
        + [dataclasses.replace(int8, rate=k) for k in (2, 3)]
        + [dataclasses.replace(base, output=o) for o in ("centre", "stitched")]
        + [dataclasses.replace(base, invalid_hands="official")])
    return [t for s in settings for t in ((s, dataclasses.replace(s, blank=True)) if pose_only else (s,))]


def replay_outputs(engine: StreamingEngine, episode: BenchEpisode, peak: list[float], blank: bool = False) -> np.ndarray:
    """Every frame through the engine (replay mode; `blank`: its images black) → (F, 2, 21, 21), NaN where
    nothing was predicted."""
    engine.reset()
    out = np.full((episode.num_frames, 2, 21, 21), np.nan, np.float32)
    for i in range(episode.num_frames):
        snapshot = episode.snapshot(i, int(time.monotonic() * 1e6))
        if blank:
            snapshot = dataclasses.replace(snapshot, images=blank_images(snapshot.images))
        for prediction in engine.step(snapshot):
            if prediction.pressure is not None:
                out[prediction.frame_index] = prediction.pressure
        peak[0] = max(peak[0], resident_mb())
    for prediction in engine.drain():
        out[prediction.frame_index] = prediction.pressure
    return out


def official_metrics(outputs: list[np.ndarray], episodes: list[BenchEpisode], bend: np.ndarray) -> dict[str, float]:
    """Per-episode official metrics over the frames with a prediction, then nanmean across episodes."""
    return aggregate([trajectory_metrics(out, episode.gt, bend) for out, episode in zip(outputs, episodes)])


def agreement(outputs: list[np.ndarray], reference: list[np.ndarray]) -> tuple[float, float]:
    """(volumetric IoU of the outputs against the reference outputs, max |difference|) over frames both have."""
    low = high = 0.0
    worst = 0.0
    for out, ref in zip(outputs, reference):
        both = ~np.isnan(out) & ~np.isnan(ref)
        low += float(np.minimum(out[both], ref[both]).sum(dtype=np.float64))
        high += float(np.maximum(out[both], ref[both]).sum(dtype=np.float64))
        worst = max(worst, float(np.abs(out[both] - ref[both]).max(initial=0.0)))
    return (low / high if high > 0 else float("nan")), worst


def interleaved_latency(engines: dict[BenchSetting, StreamingEngine], clip: list[Snapshot], rounds: int,
                        per_round: int) -> dict[BenchSetting, tuple[np.ndarray, float]]:
    """Per-frame step times (ms) and peak resident MB per setting; round 0 warms up and is discarded."""
    times = {s: [] for s in engines}
    peaks = {s: 0.0 for s in engines}
    counters = {s: 0 for s in engines}
    for round_index in range(rounds + 1):
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


def accuracy_fields(engine: StreamingEngine, episodes: list[BenchEpisode], reference: list[np.ndarray] | None,
                    bend: np.ndarray, blank: bool = False) -> tuple[dict, list[np.ndarray]]:
    """Official metrics, agreement with the reference outputs (itself when None), throughput, peak memory
    (`blank`: of the replay with every image black)."""
    peak, start = [resident_mb()], time.perf_counter()
    outputs = [replay_outputs(engine, episode, peak, blank) for episode in episodes]
    seconds = time.perf_counter() - start
    metrics = official_metrics(outputs, episodes, bend)
    agree, worst = agreement(outputs, reference or outputs)
    return {"contact_iou": metrics["contact_iou"], "volumetric_iou": metrics["volumetric_iou"], "metrics": metrics,
            "agreement_viou": agree, "agreement_max_abs": worst, "peak_rss_mb": peak[0],
            "throughput_fps": sum(e.num_frames for e in episodes) / seconds}, outputs


def setting_row(setting: BenchSetting, runtime: Runtime) -> dict:
    """A row's description of its setting, latency and accuracy not measured (None); `runtime` (the engine's,
    after the run) names device and capture."""
    gpu = torch.cuda.get_device_name(runtime.device) if runtime.device.type == "cuda" else None
    return {"preset": setting.model, "runtime": setting.runtime, "precision": setting.precision,
            "device": device_label(runtime.device), "gpu_name": gpu, "capture": runtime.capture,
            "views": "+".join(setting.views), "rate": setting.rate, "output": setting.output,
            "invalid_hands": setting.invalid_hands, "blank": setting.blank, "label": setting.label(),
            "threads": setting.engine_config(None).compute_threads(),
            "lookahead_ms": LOOKAHEAD_FRAMES[setting.output] * 1000 / 30, "p50_ms": None, "p99_ms": None,
            "mean_ms": None, "latency_frames": 0, "contact_iou": None, "volumetric_iou": None, "agreement_viou": None,
            "peak_rss_mb": 0.0}


def latency_row(setting: BenchSetting, times: np.ndarray, peak_mb: float, runtime: Runtime) -> dict:
    """The row of one setting's latency (`setting_row` with the step times in ms)."""
    return {**setting_row(setting, runtime), "p50_ms": float(np.percentile(times, 50)),
            "p99_ms": float(np.percentile(times, 99)), "mean_ms": float(times.mean()), "latency_frames": int(times.size),
            "peak_rss_mb": peak_mb}


def measured_accuracy(settings: list[BenchSetting], engines: dict[BenchSetting, StreamingEngine],
                      episodes: list[BenchEpisode], progress=print) -> dict[BenchSetting, dict]:
    """`accuracy_fields` of every setting in order (a pose-only one through its real twin's engine), agreement
    against the first setting's outputs; a pose-only setting also gets its `vision_share` of each metric."""
    bend = TactileLayout.default().bend
    accuracy: dict[BenchSetting, dict] = {}
    reference = None
    for setting in settings:
        progress(f"{setting.label()}: accuracy on {len(episodes)} episodes")
        twin = dataclasses.replace(setting, blank=False)
        accuracy[setting], outputs = accuracy_fields(engines[twin], episodes, reference, bend, setting.blank)
        if setting.blank:
            accuracy[setting]["vision_share"] = vision_shares(accuracy[twin]["metrics"], accuracy[setting]["metrics"])
        reference = reference or outputs
    return accuracy


def bench_model(name: str, model: TactileModel, episodes: list[BenchEpisode] | None, clip: list[Snapshot],
                plan: BenchPlan, progress=print) -> tuple[list[dict], dict]:
    """Rows for one model's settings (latency only, torch fp32 all views, without episodes; accuracy only for a
    pose-only baseline) and its naive comparison {naive_p50_ms, streaming_p50_ms, ratio}."""
    settings = settings_for(name, plan.quick, plan.pose_only) if episodes is not None else [BenchSetting(name)]
    with tempfile.TemporaryDirectory(prefix="touchanything-bench-") as onnx_dir:
        if any(s.runtime == "onnx" for s in settings):
            progress(f"{name}: exporting ONNX graphs")
            export_onnx(model, Path(onnx_dir), int8=True)
        engines = {s: StreamingEngine(model, s.engine_config(Path(onnx_dir) if s.runtime == "onnx" else None))
                   for s in settings if not s.blank}
        accuracy = measured_accuracy(settings, engines, episodes, progress) if episodes is not None else {}
        progress(f"{name}: interleaved latency ({plan.rounds} rounds × {plan.per_round} frames per setting)")
        latency = interleaved_latency(engines, clip, plan.rounds, plan.per_round)
    rows = []
    for setting in settings:
        runtime = engines[dataclasses.replace(setting, blank=False)].runtime
        times, peak = latency.get(setting, (None, 0.0))
        row = setting_row(setting, runtime) if times is None else latency_row(setting, times, peak, runtime)
        row.update(accuracy.get(setting, {}))
        row["peak_rss_mb"] = max(peak, accuracy.get(setting, {}).get("peak_rss_mb", 0.0))
        rows.append(row)
    progress(f"{name}: naive recompute ({plan.naive_steps} frames)")
    naive = float(np.median(naive_latency(model, clip, plan.naive_steps)))
    streaming = rows[0]["p50_ms"]
    return rows, {"naive_p50_ms": naive, "streaming_p50_ms": streaming, "ratio": naive / streaming}
