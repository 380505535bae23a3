"""The accuracy half of `touchanything bench`: every setting of one model replays the held-out trajectories
frame by frame through the streaming engine (replay mode: every frame processed, deterministic), with the
official metrics per trajectory (an ensemble's also the rank correlation of its members' spread with its error,
`spread_error`), the agreement of its outputs with the model's reference setting (the first
one), its throughput and peak memory.

With `workers` > 1 the trajectories are dealt out to worker processes (worker w takes trajectories w, w + N,
…; each loads the checkpoint and its own trajectories and runs every setting on them) and the parts are put
back in trajectory order: the figures are the same as one process's, the wall time about N times shorter on
N free cores. Latency is never measured here (`bench.interleaved_latency` times it in one process).
"""
from __future__ import annotations

import dataclasses
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.ensemble_engine import engine_for
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.evaluation.bench_data import BenchEpisode, load_episodes, resident_mb
from touchanything.inference.evaluation.bench_intervals import SPREAD_ERROR
from touchanything.inference.evaluation.evaluation import trajectory_metrics
from touchanything.inference.evaluation.spread_error import trajectory_correlation
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.preprocess import blank_images


@dataclass(frozen=True)
class HeldOut:
    """What accuracy is measured on: (trajectory path, split) pairs, the first `frames` frames of each (None: all),
    replayed in `workers` processes."""

    pairs: list[tuple[Path, str]]
    frames: int | None = None
    workers: int = 1


@dataclass
class SettingAccuracy:
    """One setting's replay of some trajectories: official metrics per trajectory (in trajectory order; an
    ensemble's with its SPREAD_ERROR); the
    agreement sums with the reference outputs (Σ min, Σ max, max |difference| over the frames both predicted);
    frames replayed, seconds spent, peak resident MB."""

    per_trajectory: list[dict[str, float]] = field(default_factory=list)
    low: float = 0.0
    high: float = 0.0
    worst: float = 0.0
    frames: int = 0
    seconds: float = 0.0
    peak_mb: float = 0.0

    @property
    def agreement_viou(self) -> float:
        """Volumetric IoU of the outputs against the reference outputs (NaN when neither predicted anything)."""
        return self.low / self.high if self.high > 0 else float("nan")

    @property
    def throughput_fps(self) -> float:
        """Frames per second of one engine replaying (every worker's frames over every worker's seconds)."""
        return self.frames / self.seconds if self.seconds > 0 else float("nan")


@dataclass
class ModelAccuracy:
    """Every setting's `SettingAccuracy` over the trajectories that loaded (`names`, `splits`, in order) and one
    line per trajectory that did not."""

    names: list[str]
    splits: list[str]
    settings: dict[EngineSetting, SettingAccuracy]
    failures: list[str]


@dataclass(frozen=True)
class Replayed:
    """One trajectory through an engine: pressure (F, 2, 21, 21), NaN where nothing was predicted; spread (F, 2, 21,
    21), an ensemble's members' standard deviation per cell (NaN where none; None for a single model); hands (F, 2)
    bool, the hands each frame's prediction covered."""

    pressure: np.ndarray
    spread: np.ndarray | None
    hands: np.ndarray


def replay_outputs(engine: StreamingEngine, episode: BenchEpisode, peak: list[float], blank: bool = False) -> Replayed:
    """Every frame through the engine (replay mode; `blank`: its images black)."""
    engine.reset()
    shape = (episode.num_frames, 2, 21, 21)
    out, spread = np.full(shape, np.nan, np.float32), np.full(shape, np.nan, np.float32)
    hands, ensemble = np.zeros((episode.num_frames, 2), bool), False

    def keep(prediction) -> None:
        nonlocal ensemble
        if prediction.pressure is None:
            return
        out[prediction.frame_index] = prediction.pressure
        hands[prediction.frame_index] = prediction.hands_predicted
        if prediction.spread is not None:
            spread[prediction.frame_index], ensemble = prediction.spread, True

    for i in range(episode.num_frames):
        snapshot = episode.snapshot(i, int(time.monotonic() * 1e6))
        if blank:
            snapshot = dataclasses.replace(snapshot, images=blank_images(snapshot.images))
        for prediction in engine.step(snapshot):
            keep(prediction)
        peak[0] = max(peak[0], resident_mb())
    for prediction in engine.drain():
        keep(prediction)
    return Replayed(out, spread if ensemble else None, hands)


def agreement_sums(out: np.ndarray, ref: np.ndarray) -> tuple[float, float, float]:
    """(Σ min, Σ max, max |difference|) of two outputs over the cells both have."""
    both = ~np.isnan(out) & ~np.isnan(ref)
    return (float(np.minimum(out[both], ref[both]).sum(dtype=np.float64)),
            float(np.maximum(out[both], ref[both]).sum(dtype=np.float64)),
            float(np.abs(out[both] - ref[both]).max(initial=0.0)))


def settings_accuracy(settings: list[EngineSetting], engines: dict[EngineSetting, StreamingEngine],
                      episodes: list[BenchEpisode], progress=print) -> dict[EngineSetting, SettingAccuracy]:
    """Every setting in order over `episodes`, agreement against the first setting's outputs (a pose-only setting,
    `blank`, runs through its real twin's engine)."""
    bend = TactileLayout.default().bend
    results: dict[EngineSetting, SettingAccuracy] = {}
    reference: list[np.ndarray] | None = None
    for setting in settings:
        progress(f"{setting.name()}: accuracy on {len(episodes)} trajectories")
        engine = engines[dataclasses.replace(setting, blank=False)]
        result, outputs, peak, start = SettingAccuracy(), [], [resident_mb()], time.perf_counter()
        for index, episode in enumerate(episodes):
            replayed = replay_outputs(engine, episode, peak, setting.blank)
            out = replayed.pressure
            result.per_trajectory.append(trajectory_metrics(out, episode.gt, bend))
            if replayed.spread is not None:
                result.per_trajectory[-1][SPREAD_ERROR] = trajectory_correlation(out, replayed.spread, episode.gt,
                                                                                 replayed.hands)
            low, high, worst = agreement_sums(out, out if reference is None else reference[index])
            result.low, result.high, result.worst = result.low + low, result.high + high, max(result.worst, worst)
            result.frames += episode.num_frames
            if reference is None:
                outputs.append(out)
        result.seconds, result.peak_mb = time.perf_counter() - start, peak[0]
        reference = reference if reference is not None else outputs
        results[setting] = result
    return results


def model_accuracy(model: TactileModel, checkpoint: Path | None, settings: list[EngineSetting],
                   engines: dict[EngineSetting, StreamingEngine], onnx_dir: Path | None, held_out: HeldOut,
                   progress=print) -> ModelAccuracy:
    """`settings_accuracy` over the held-out trajectories, in this process (`engines`) or, with `workers` > 1, in
    worker processes that load `checkpoint` and build their own engines (the ONNX graphs from `onnx_dir`)."""
    size = model.config.image_size
    if held_out.workers <= 1:
        progress(f"reading {len(held_out.pairs)} held-out trajectories")
        episodes, failures = load_episodes(held_out.pairs, size, held_out.frames)
        return ModelAccuracy([e.name for e in episodes], [e.split for e in episodes],
                             settings_accuracy(settings, engines, episodes, progress), failures)
    if checkpoint is None:
        raise ValueError("worker processes need the model's checkpoint")
    workers = min(held_out.workers, len(held_out.pairs))
    threads = max(1, (os.cpu_count() or 1) // workers)
    shares = [list(range(w, len(held_out.pairs), workers)) for w in range(workers)]
    jobs = [(checkpoint, settings, [held_out.pairs[i] for i in share], size, held_out.frames, onnx_dir, threads,
             f"worker {w + 1}/{workers}") for w, share in enumerate(shares)]
    progress(f"{len(settings)} settings on {len(held_out.pairs)} trajectories in {workers} worker processes")
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        parts = list(pool.map(_worker, jobs))
    return _merged(parts, shares, settings)


WorkerPart = tuple[list[int], list[str], list[str], dict[EngineSetting, SettingAccuracy], list[str]]
"""(positions of the loaded trajectories in the worker's share, their names, their splits, results, failures)"""


def _worker(job) -> WorkerPart:
    """One worker's share: load the checkpoint and its trajectories, build the engines, replay."""
    from touchanything.inference.model.checkpoint import load_model

    checkpoint, settings, pairs, size, frames, onnx_dir, threads, tag = job
    model = load_model(checkpoint)
    engines = {s: engine_for(model, checkpoint, s, onnx_dir if s.runtime == "onnx" else None, threads)
               for s in settings if not s.blank}
    def progress(message: str) -> None:
        print(f"  [{tag}] {message}", file=sys.stderr, flush=True)

    progress(f"reading {len(pairs)} trajectories")
    episodes, failures = load_episodes(pairs, size, frames)
    where = {Path(path): position for position, (path, _) in enumerate(pairs)}

    return ([where[e.path] for e in episodes], [e.name for e in episodes], [e.split for e in episodes],
            settings_accuracy(settings, engines, episodes, progress), failures)


def _merged(parts: list[WorkerPart], shares: list[list[int]], settings: list[EngineSetting]) -> ModelAccuracy:
    """The workers' parts back in the order of the held-out trajectories (`shares[w]`: worker w's indices)."""
    order = sorted((shares[w][position], w, k) for w, part in enumerate(parts) for k, position in enumerate(part[0]))
    results = {}
    for setting in settings:
        pieces = [part[3][setting] for part in parts]
        results[setting] = SettingAccuracy(
            [pieces[w].per_trajectory[k] for _, w, k in order], sum(x.low for x in pieces), sum(x.high for x in pieces),
            max(x.worst for x in pieces), sum(x.frames for x in pieces), sum(x.seconds for x in pieces),
            max(x.peak_mb for x in pieces))
    return ModelAccuracy([parts[w][1][k] for _, w, k in order], [parts[w][2][k] for _, w, k in order], results,
                         [line for part in parts for line in part[4]])
