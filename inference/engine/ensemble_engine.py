"""EnsembleEngine: K streaming engines, one per ensemble member (`inference/model/ensemble_members.py`), fed the
same snapshots; each output is the per-cell mean of the members' pressures with their spread.

The members run one after the other on the caller's thread, at the same setting, so they emit the same frames
in the same order; each torch member runs its own modules, each ONNX member the user cache's export of its own
weights (member 1 may run a given export folder). It answers to what callers use of a `StreamingEngine`:
`step`, `drain`, `reset`, `set_views`, `setting`, `runtime`, `blank`, `image_size`.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from touchanything.core.errors import UserError
from touchanything.core.snapshot import Snapshot
from touchanything.core.tactile_layout import TactileLayout
from touchanything.inference.engine.engine_runtime import Runtime
from touchanything.inference.engine.engine_setting import EngineSetting
from touchanything.inference.engine.prediction import Prediction
from touchanything.inference.engine.streaming_engine import StreamingEngine
from touchanything.inference.model.checkpoint import load_model
from touchanything.inference.model.ensemble_members import member_checkpoints
from touchanything.inference.model.models import TactileModel


def member_mean(pressures: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 2, 21, 21) members' pressures → their per-cell mean and population standard deviation, float32.
    A member's NaN or infinite value leaves that cell to the other members; a cell no member has (outside
    the hand layout) is NaN in both. K identical maps give exactly that map and 0."""
    stack = np.asarray(pressures, np.float64)
    finite = np.isfinite(stack)
    count = finite.sum(axis=0)
    values = np.where(finite, stack, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, values.sum(axis=0) / count, np.nan)
        deviation = np.where(finite, stack - mean, 0.0)
        spread = np.where(count > 0, np.sqrt((deviation ** 2).sum(axis=0) / count), np.nan)
    return mean.astype(np.float32), spread.astype(np.float32)


def combine(predictions: list[Prediction]) -> Prediction:
    """The members' predictions of one frame → the ensemble's: mean pressure and spread, timings summed per
    stage, latency of the last member; the rest as member 1 says (all members see the same snapshots)."""
    first, last = predictions[0], predictions[-1]
    timings: dict[str, float] = {}
    for p in predictions:
        for stage, ms in p.timings_ms.items():
            timings[stage] = timings.get(stage, 0.0) + ms
    pressure = spread = None
    if first.pressure is not None:
        pressure, spread = member_mean(np.stack([p.pressure for p in predictions]))
    return dataclasses.replace(first, pressure=pressure, spread=spread, timings_ms=timings, latency_ms=last.latency_ms)


class EnsembleEngine:
    """`StreamingEngine`'s interface over `setting.members` models (one per member, member 1 first)."""

    def __init__(self, models: list[TactileModel], setting: EngineSetting, layout: TactileLayout | None = None,
                 clock: Callable[[], float] = time.monotonic, onnx_dir: Path | None = None,
                 threads: int | None = None) -> None:
        """`onnx_dir`: member 1's export folder (the others run the user cache's exports of their weights)."""
        if len(models) != setting.members:
            raise UserError(f"setting {setting.name()} asks for {setting.members} members, {len(models)} models given")
        single = dataclasses.replace(setting, members=1)
        self.setting = setting
        self.members = [StreamingEngine(m, single, layout, clock, onnx_dir if i == 0 else None, threads)
                        for i, m in enumerate(models)]

    @property
    def runtime(self) -> Runtime:
        """Member 1's runtime (every member's has the same name, precision and device)."""
        return self.members[0].runtime

    @property
    def blank(self) -> bool:
        return self.members[0].blank

    @property
    def image_size(self) -> int:
        return self.members[0].image_size

    def reset(self) -> None:
        for member in self.members:
            member.reset()

    def set_views(self, views: tuple[str, ...]) -> None:
        """Change the views every member may use, mid-stream."""
        self.setting = dataclasses.replace(self.setting, views=tuple(views))
        for member in self.members:
            member.set_views(views)

    def step(self, snapshot: Snapshot) -> list[Prediction]:
        return [combine(list(frame)) for frame in zip(*(m.step(snapshot) for m in self.members), strict=True)]

    def drain(self) -> list[Prediction]:
        """End of stream: what the members' look-ahead still holds, combined."""
        return [combine(list(frame)) for frame in zip(*(m.drain() for m in self.members), strict=True)]


def load_ensemble(checkpoint: Path, setting: EngineSetting, config: Path | None = None, onnx_dir: Path | None = None,
                  threads: int | None = None) -> EnsembleEngine:
    """The engine of `checkpoint`'s ensemble at `setting` (its first `setting.members` members, checked by
    `member_checkpoints`); `config`: member 1's config (None: beside it). UserError for a bad ensemble."""
    paths = member_checkpoints(checkpoint, setting.members, config)
    models = [load_model(path, config if i == 0 else None) for i, path in enumerate(paths)]
    return EnsembleEngine(models, setting, onnx_dir=onnx_dir, threads=threads)


def engine_for(model: TactileModel, checkpoint: Path | None, setting: EngineSetting, onnx_dir: Path | None = None,
               threads: int | None = None) -> StreamingEngine | EnsembleEngine:
    """The engine of `setting` for `model`, loaded from `checkpoint`: a StreamingEngine of `model` itself, or with
    `members` > 1 the ensemble of `checkpoint` (UserError without a checkpoint). `onnx_dir`: member 1's export."""
    if setting.members == 1:
        return StreamingEngine(model, setting, onnx_dir=onnx_dir, threads=threads)
    if checkpoint is None:
        raise UserError(f"setting {setting.name()}: an ensemble is loaded from its checkpoint's folder; none given")
    return load_ensemble(checkpoint, setting, onnx_dir=onnx_dir, threads=threads)
