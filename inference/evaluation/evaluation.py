"""The official evaluation protocol on HDF5 trajectories, plus causal newest-frame predictions.

Per trajectory: every clip start 0…T−15 (stride 1, 8 frames, interval 2); each frame's stitched prediction
is the average over all clips that contain it; its causal prediction is the last frame of the clip that
ends on it (frames 0–13 have none). Metrics per trajectory (`touchanything.inference.evaluation.metrics`), then nanmean overall and
per scene category (the parent of the task folder). `--views ego` uses the official `frames=` path unless
`ego_path="views"` asks for the multi-view encoder.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from touchanything.devices.episodes.episode import Episode
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.devices.errors import UserError
from touchanything.devices.snapshot import VIEW_NAMES
from touchanything.devices.tactile_layout import TactileLayout
from touchanything.inference.evaluation.metrics import MetricAccumulator, aggregate, ground_truth_for_metrics
from touchanything.inference.model.model_config import CLIP_LENGTH, FRAME_INTERVAL, SPAN
from touchanything.inference.model.pose_encoder import prepare_poses
from touchanything.inference.model.preprocess import resize_frame, to_model_input
from touchanything.inference.model.touch_model import TouchAnything

VIEW_SETS = {"ego": ("ego",), "ego+left": ("ego", "wrist_left"), "ego+right": ("ego", "wrist_right"), "all": VIEW_NAMES}


@dataclass
class TrajectoryPrediction:
    """stitched, causal: (T, 2, 21, 21) float32, NaN where a frame has no prediction."""

    stitched: np.ndarray
    causal: np.ndarray


def _frames(episode: Episode, view: str, size: int) -> np.ndarray:
    source = episode.views.get(view)
    if source is None:
        raise UserError(f"{episode.path}: view {view} is missing; evaluate with fewer views")
    out = np.empty((episode.num_frames, size, size, 3), np.uint8)
    for i in range(episode.num_frames):
        image = source.read(i)
        if image is None:
            raise UserError(f"{episode.path}: view {view} has no frame {i}")
        out[i] = resize_frame(image, size)
    return out


@torch.no_grad()
def predict_trajectory(model: TouchAnything, episode: Episode, views: tuple[str, ...], batch_size: int = 16,
                       ego_path: str = "frames") -> TrajectoryPrediction:
    """Run every stride-1 clip of the trajectory through the batch model."""
    frames_count = episode.num_frames
    stitched_sum = np.zeros((frames_count, 2, 21, 21), np.float64)
    counts = np.zeros(frames_count, np.int64)
    causal = np.full((frames_count, 2, 21, 21), np.nan, np.float32)
    if frames_count < SPAN or episode.wilor is None:
        return TrajectoryPrediction(np.full_like(causal, np.nan), causal)
    size = model.config.image_size
    images = {v: _frames(episode, v, size) for v in views}
    poses = prepare_poses(episode.wilor.joints.reshape(frames_count, 42, 3), episode.wilor.valid)
    starts = np.arange(frames_count - SPAN + 1)
    offsets = np.arange(CLIP_LENGTH) * FRAME_INTERVAL
    for first in range(0, len(starts), batch_size):
        index = starts[first:first + batch_size, None] + offsets[None]
        inputs = {v: to_model_input(images[v][index]) for v in views}
        pose = torch.from_numpy(poses[index])
        if views == ("ego",) and ego_path == "frames":
            out = model(frames=inputs["ego"], poses=pose)["tactile"]
        else:
            out = model(poses=pose, views=inputs)["tactile"]
        out = out.float().numpy()
        np.add.at(stitched_sum, index.ravel(), out.reshape(-1, 2, 21, 21))
        np.add.at(counts, index.ravel(), 1)
        causal[index[:, -1]] = out[:, -1]
    stitched = np.full((frames_count, 2, 21, 21), np.nan, np.float32)
    covered = counts > 0
    stitched[covered] = (stitched_sum[covered] / counts[covered, None, None, None]).astype(np.float32)
    return TrajectoryPrediction(stitched, causal)


def trajectory_metrics(prediction: np.ndarray, gt: np.ndarray, bend: np.ndarray) -> dict[str, float]:
    """Metrics over the frames that have a prediction."""
    has = ~np.all(np.isnan(prediction.reshape(len(prediction), -1)), axis=1)
    accumulator = MetricAccumulator(bend)
    if has.any():
        accumulator.add(prediction[has], gt[has])
    return accumulator.result()


@dataclass
class EvaluationResult:
    """rows: one dict per trajectory (path, scene, task, frames, stitched/causal metrics)."""

    views: str
    rows: list[dict]

    def summary(self, mode: str) -> dict[str, dict[str, float]]:
        """{"overall" | scene: nanmean metrics} for mode "stitched" or "causal"."""
        scenes = sorted({r["scene"] for r in self.rows})
        out = {"overall": aggregate([r[mode] for r in self.rows])}
        out.update({scene: aggregate([r[mode] for r in self.rows if r["scene"] == scene]) for scene in scenes})
        return out


def evaluate(model: TouchAnything, files: list[Path], views: str, batch_size: int = 16, ego_path: str = "frames",
             on_trajectory: Callable[[dict, Episode, TrajectoryPrediction, np.ndarray], None] | None = None
             ) -> EvaluationResult:
    """The official protocol over HDF5 (or raw) trajectories for one view configuration.

    `on_trajectory(row, episode, prediction, gt)` is called while each episode is still open."""
    if views not in VIEW_SETS:
        raise UserError(f"unknown --views {views!r}; choose from {', '.join(VIEW_SETS)}")
    bend = TactileLayout.default().bend
    rows = []
    for path in files:
        with open_episode(path) as episode:
            if episode.pressure is None:
                raise UserError(f"{path}: no ground-truth pressure; cannot evaluate")
            prediction = predict_trajectory(model, episode, VIEW_SETS[views], batch_size, ego_path)
            gt = ground_truth_for_metrics(episode.pressure.grids, bool(episode.pressure.attrs.get("normalized", False)))
            row = {"path": str(path), "scene": episode.scene, "task": episode.task, "frames": episode.num_frames,
                   "stitched": trajectory_metrics(prediction.stitched, gt, bend),
                   "causal": trajectory_metrics(prediction.causal, gt, bend)}
            on_trajectory and on_trajectory(row, episode, prediction, gt)
        rows.append(row)
    return EvaluationResult(views, rows)
