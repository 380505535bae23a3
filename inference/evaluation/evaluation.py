"""The official evaluation protocol on HDF5 trajectories, plus causal newest-frame predictions.

Per trajectory: every clip start 0…T−15 (stride 1, 8 frames, interval 2); each frame's stitched prediction
is the average over all clips that contain it; its causal prediction is the last frame of the clip that
ends on it (frames 0–13 have none); each frame is encoded once (`trajectory_prediction`). Metrics per
trajectory (`touchanything.inference.evaluation.metrics`), then nanmean overall and per scene category (the
parent of the task folder). `--views ego` uses the official `frames=` path unless
`ego_path="views"` asks for the multi-view encoder. `blank=True` is the pose-only baseline: the same protocol
with every frame of every used view black (`preprocess.blank_frames`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch.distributed as dist

from touchanything.core.errors import UserError, failure_line
from touchanything.core.tactile_layout import TactileLayout
from touchanything.core.view_sets import VIEW_SETS
from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.inference.evaluation.metrics import MetricAccumulator, aggregate, ground_truth_for_metrics
from touchanything.inference.evaluation.trajectory_prediction import TrajectoryPrediction, predict_trajectory
from touchanything.inference.evaluation.vision_share import vision_shares
from touchanything.inference.model.models import TactileModel
from touchanything.inference.model.torch_device import ProcessGroup


def trajectory_metrics(prediction: np.ndarray, gt: np.ndarray, bend: np.ndarray) -> dict[str, float]:
    """Metrics over the frames that have a prediction."""
    has = ~np.all(np.isnan(prediction.reshape(len(prediction), -1)), axis=1)
    accumulator = MetricAccumulator(bend)
    if has.any():
        accumulator.add(prediction[has], gt[has])
    return accumulator.result()


@dataclass
class EvaluationResult:
    """rows: one dict per trajectory (path, scene, task, frames, stitched/causal metrics); blank: the
    pose-only twin (images blanked); baseline: the name of a baseline model evaluated beside the model ("" for
    the model itself); failures: one line per trajectory that could not be evaluated (not in `rows`)."""

    views: str
    rows: list[dict]
    blank: bool = False
    baseline: str = ""
    failures: list[str] = field(default_factory=list)

    @property
    def label(self) -> str:
        if self.baseline:
            return f"{self.views} · {self.baseline}"
        return f"{self.views} (pose only)" if self.blank else self.views

    def summary(self, mode: str) -> dict[str, dict[str, float]]:
        """{"overall" | scene: nanmean metrics} for mode "stitched" or "causal"."""
        scenes = sorted({r["scene"] for r in self.rows})
        out = {"overall": aggregate([r[mode] for r in self.rows])}
        out.update({scene: aggregate([r[mode] for r in self.rows if r["scene"] == scene]) for scene in scenes})
        return out


def vision_share_summary(real: EvaluationResult, blank: EvaluationResult, mode: str) -> dict[str, dict[str, float]]:
    """{"overall" | scene: {metric: share}}: the share of `real`'s summary that vision carries against its
    pose-only baseline `blank` (same files and views), from the summary values (`vision_share`)."""
    baseline = blank.summary(mode)
    return {scene: vision_shares(metrics, baseline[scene]) for scene, metrics in real.summary(mode).items()}


def evaluate(model: TactileModel, files: list[Path], views: str, batch_size: int = 16, ego_path: str = "frames",
             precision: str = "fp32", group: ProcessGroup = ProcessGroup(),
             on_trajectory: Callable[[dict, Episode, TrajectoryPrediction, np.ndarray], None] | None = None,
             on_frames: Callable[[int], None] | None = None, blank: bool = False) -> EvaluationResult:
    """The official protocol over HDF5 (or raw) trajectories for one view configuration, on the model's device
    (`blank`, or a model trained on black frames (`config.blank_images`): with every frame of those views
    black, the pose-only baseline).

    Under `torchrun` (group.world > 1) process r evaluates files r, r + world, …; every process returns all
    rows, in `files` order, so the result equals one process's. `on_trajectory(row, episode, prediction, gt)`
    is called (in the process that evaluated it) while each episode is still open; `on_frames(n)` as frames
    are encoded."""
    if views not in VIEW_SETS:
        raise UserError(f"unknown --views {views!r}; choose from {', '.join(VIEW_SETS)}")
    bend = TactileLayout.default().bend
    rows = []
    for position in range(group.rank, len(files), group.world):
        path = files[position]
        try:
            with open_episode(path) as episode:
                if episode.pressure is None:
                    raise UserError(f"{path}: no ground-truth pressure; cannot evaluate")
                prediction = predict_trajectory(model, episode, VIEW_SETS[views], batch_size, ego_path, precision,
                                                on_frames, blank or model.config.blank_images)
                gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
                row = {"path": str(path), "scene": episode.scene, "task": episode.task, "frames": episode.num_frames,
                       "stitched": trajectory_metrics(prediction.stitched, gt, bend),
                       "causal": trajectory_metrics(prediction.causal, gt, bend)}
                on_trajectory and on_trajectory(row, episode, prediction, gt)
        except Exception as exc:  # noqa: BLE001 - one trajectory that fails is named; the others are evaluated
            row = {"path": str(path), "error": failure_line(path, exc)}
        rows.append((position, row))
    if group.world > 1:
        gathered: list[list] = [[] for _ in range(group.world)]
        dist.all_gather_object(gathered, rows)
        rows = [item for part in gathered for item in part]
    ordered = [row for _, row in sorted(rows, key=lambda item: item[0])]
    return EvaluationResult(views, [r for r in ordered if "error" not in r], blank,
                            failures=[r["error"] for r in ordered if "error" in r])
