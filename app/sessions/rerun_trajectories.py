"""Evaluated trajectories into one .rrd file (`eval --rerun FILE.rrd`): each trajectory (and view configuration)
is a recording of its own, written to a part file beside the output while the evaluation runs, and the parts
are merged into the output at the end (Rerun's `rrd merge` keeps them as separate recordings)."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from touchanything.app.sessions.rerun_output import merge_recordings
from touchanything.core.snapshot import TRACKER_ROLES, VIEW_NAMES
from touchanything.core.temporary_files import mark, temporary_path, unmark
from touchanything.devices.episodes.episode import Episode
from touchanything.inference.evaluation.running_metrics import RunningMetrics
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget


class TrajectoryRecordings:
    """`add` each evaluated trajectory; `close()` merges them into `out` (and removes the parts)."""

    def __init__(self, out: Path, bend: np.ndarray, properties: dict[str, str]) -> None:
        self.out = out
        self.bend = bend
        self.properties = properties
        self.parts_dir = temporary_path(out.with_suffix(".parts"))
        self.parts: list[Path] = []

    def add(self, name: str, episode: Episode, predicted: np.ndarray, truth: np.ndarray,
            used: tuple[str, ...] = VIEW_NAMES) -> None:
        """One trajectory: its frames, poses, trackers and measured maps beside the predicted (T, 2, 21, 21)
        (NaN where no clip covers a frame), shown on the ground truth's layout mask as in the videos; the views
        outside `used` (those the model took nothing from) marked "not used"."""
        if not self.parts_dir.is_dir():
            self.parts_dir.parent.mkdir(parents=True, exist_ok=True)
            mark(self.parts_dir, "folder")
            self.parts_dir.mkdir()
        part = self.parts_dir / f"{len(self.parts):05d}.rrd"
        recording = RerunRecording(RerunTarget(part), name, {**self.properties, "episode": str(episode.path)})
        metrics = RunningMetrics(self.bend)
        try:
            for i in range(episode.num_frames):
                self._frame(recording, episode, i, predicted[i], truth[i], metrics, used)
        finally:
            recording.close()
        self.parts.append(part)

    def _frame(self, recording: RerunRecording, episode: Episode, i: int, predicted: np.ndarray, truth: np.ndarray,
               metrics: RunningMetrics, used: tuple[str, ...]) -> None:
        time_s = float(episode.timestamps_us[i]) / 1e6
        images = {v: image for v, source in episode.views.items() if (image := source.read(i)) is not None}
        hands = episode.wilor
        joints = hands.joints[i].reshape(42, 3) if hands is not None else np.zeros((42, 3), np.float32)
        valid = hands.valid[i] if hands is not None else np.zeros(2, bool)
        trackers = {} if episode.trackers is None else {role: episode.trackers.poses[i, r] for r, role in enumerate(TRACKER_ROLES)
                                                        if episode.trackers.valid[i, r]}
        shown = np.where(np.isnan(truth), np.nan, predicted)
        if not np.isfinite(shown).any():
            facts = frame_facts(None, None, truth, self.bend)
            recording.log_observation(i, time_s, images, joints, valid, truth, facts, trackers, used)
            recording.log_prediction(i, time_s, None, facts, joints, valid, truth, None, None)
            return
        metrics.add(shown, truth)
        facts = frame_facts(shown, None, truth, self.bend, metrics=metrics)
        recording.log_observation(i, time_s, images, joints, valid, truth, facts, trackers, used)
        recording.log_prediction(i, time_s, shown, facts, joints, valid, truth, None, None)

    def close(self) -> None:
        """Merge the parts into the output (renamed into place); a failure leaves no part behind."""
        try:
            if self.parts:
                merge_recordings(self.parts, self.out)
        finally:
            shutil.rmtree(self.parts_dir, ignore_errors=True)
            unmark(self.parts_dir)
